//! Every shader parses and validates with naga, in f32 and in f64, without a GPU.

use naga::valid::{Capabilities, ValidationFlags, Validator};
use rattle::gpu::shader_source;

fn validate(src: &str, caps: Capabilities) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| e.emit_to_string(src))?;
    Validator::new(ValidationFlags::all(), caps)
        .validate(&module)
        .map_err(|e| e.emit_to_string(src))?;
    Ok(())
}

#[test]
fn integrate_f32_validates() {
    validate(&shader_source(false), Capabilities::empty()).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn integrate_f64_validates() {
    let src = shader_source(true);
    assert!(src.contains("alias F = f64;"));
    validate(&src, Capabilities::FLOAT64).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn f64_variant_needs_the_float64_capability() {
    // Guards against the alias rewrite silently leaving the kernel in f32.
    assert!(validate(&shader_source(true), Capabilities::empty()).is_err());
}

#[test]
fn f64_kernel_uses_no_transcendental_builtins() {
    let src = shader_source(true);
    for f in [
        "cos(", "sin(", "exp(", "log(", "pow(", "tan(", "floor(", "abs(",
    ] {
        let hits = src.match_indices(f).filter(|(i, _)| {
            // Only whole-word calls count (not `fabs(` or `cos_sin_small(`), and not the one
            // logarithm the Lyapunov estimate takes in f32 on purpose.
            let word = *i == 0
                || !src.as_bytes()[i - 1].is_ascii_alphanumeric() && src.as_bytes()[i - 1] != b'_';
            word && !src[*i..].starts_with("log(f32(")
        });
        assert_eq!(hits.count(), 0, "f64 kernel calls {f}");
    }
}
