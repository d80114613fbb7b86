//! Every shader parses and validates with naga, in f32 and in f64, without a GPU; and the
//! kernel holds the host/kernel contract of src/gpu/layout.rs as the host sees it.

use naga::valid::{Capabilities, ValidationFlags, Validator};
use rattle::config::Precision;
use rattle::gpu::layout::{self, Control};
use rattle::gpu::shader_source;

fn parse(src: &str) -> naga::Module {
    naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)))
}

fn validate(src: &str, caps: Capabilities) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| e.emit_to_string(src))?;
    Validator::new(ValidationFlags::all(), caps)
        .validate(&module)
        .map_err(|e| e.emit_to_string(src))?;
    Ok(())
}

#[test]
fn integrate_f32_validates() {
    validate(&shader_source(Precision::F32), Capabilities::empty())
        .unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn integrate_f64_validates() {
    let src = shader_source(Precision::F64);
    assert!(src.contains("alias F = f64;"));
    validate(&src, Capabilities::FLOAT64).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn f64_variant_needs_the_float64_capability() {
    // Guards against the f64 kernel silently staying in f32.
    assert!(validate(&shader_source(Precision::F64), Capabilities::empty()).is_err());
}

#[test]
fn f64_kernel_uses_no_transcendental_builtins() {
    let src = shader_source(Precision::F64);
    for f in [
        "cos(", "sin(", "exp(", "log(", "pow(", "tan(", "floor(", "abs(",
    ] {
        let hits = src.match_indices(f).filter(|(i, _)| {
            // Only whole-word calls count (not `fabs(` or `cos_sin_small(`), and not the
            // logarithm of the Lyapunov estimate and the exponential of the torus test's weight,
            // taken in f32 on purpose.
            let word = *i == 0
                || !src.as_bytes()[i - 1].is_ascii_alphanumeric() && src.as_bytes()[i - 1] != b'_';
            word && !src[*i..].starts_with("log(f32(") && !src[*i..].starts_with("exp(f32(")
        });
        assert_eq!(hits.count(), 0, "f64 kernel calls {f}");
    }
}

#[test]
fn kernel_body_declares_none_of_the_contract() {
    // The precision and the contract come only from the generated prelude.
    // Declarations only, not the comments that mention them.
    let code: Vec<&str> = rattle::gpu::SHADER
        .lines()
        .map(|l| l.split("//").next().unwrap().trim())
        .collect();
    let declares = |start: &str| code.iter().any(|l| l.starts_with(start));
    assert!(!declares("alias F"), "the kernel declares its precision");
    assert!(!declares("struct Control"), "the kernel declares Control");
    for (name, _) in layout::constants() {
        assert!(
            !declares(&format!("const {name}:")),
            "the kernel declares {name}"
        );
    }
}

#[test]
fn kernel_constants_have_the_host_values() {
    for precision in [Precision::F32, Precision::F64] {
        let module = parse(&shader_source(precision));
        let constants = layout::constants();
        assert!(constants.len() > 60, "{} constants", constants.len());
        for (name, value) in constants {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("{name} is not a constant of the kernel"));
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(v)) => {
                    assert_eq!(v, value, "{name}: kernel {v}, host {value}")
                }
                ref e => panic!("{name} is {e:?}, not a u32 literal"),
            }
        }
    }
}

#[test]
fn kernel_control_matches_the_host_struct() {
    let module = parse(&shader_source(Precision::F32));
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Control"))
        .expect("Control in the kernel");
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("Control is {:?}", ty.inner);
    };
    let kernel: Vec<(&str, usize)> = members
        .iter()
        .map(|m| (m.name.as_deref().unwrap(), m.offset as usize))
        .collect();
    assert_eq!(kernel, Control::MEMBERS);
    // The host's own offsets, to catch a member list out of step with the struct.
    assert_eq!(
        Control::MEMBERS
            .iter()
            .find(|(n, _)| *n == "lyap")
            .map(|m| m.1),
        Some(std::mem::offset_of!(Control, lyap))
    );
    assert_eq!(*span as usize, size_of::<Control>());
    assert_eq!(
        size_of::<Control>() % 16,
        0,
        "uniform size not a multiple of 16"
    );
}

#[test]
fn slots_are_distinct_and_inside_their_buffers() {
    let constants = layout::constants();
    let group = |prefix: &str, count: &str| {
        let total = constants.iter().find(|c| c.0 == count).unwrap().1;
        let mut slots: Vec<u32> = constants
            .iter()
            .filter(|c| c.0.starts_with(prefix) && c.0 != count)
            .map(|c| c.1)
            .collect();
        slots.sort();
        let n = slots.len();
        slots.dedup();
        assert_eq!(slots.len(), n, "{prefix}* slots repeat");
        assert!(slots.iter().all(|&s| s < total), "{prefix}* beyond {count}");
    };
    group("U_", "U_SLOTS");
    group("R_", "R_SLOTS");
    group("C_", "C_TABLE");
    group("VARY_", "VARY_NONE");
    group("MODE_", "VARY_NONE");
    group("EV_", "VARY_NONE");
    // The ring's named slots follow its TAIL values; states fit their slots.
    assert_eq!(layout::R_LO, layout::TAIL);
    assert_eq!(layout::Y_SLOTS, 2 * layout::STATE_DIM);
}

#[test]
fn kernel_bindings_match_the_host_layout() {
    let module = parse(&shader_source(Precision::F32));
    let mut bound: Vec<(String, u32)> = module
        .global_variables
        .iter()
        .filter_map(|(_, g)| Some((g.name.clone()?, g.binding.as_ref()?)))
        .map(|(name, b)| {
            assert_eq!(b.group, 0, "{name} is in group {}", b.group);
            (name, b.binding)
        })
        .collect();
    bound.sort_by_key(|(_, b)| *b);
    let mut host: Vec<(String, u32)> = layout::BINDINGS
        .iter()
        .map(|(n, b)| (n.to_string(), *b))
        .collect();
    host.sort_by_key(|(_, b)| *b);
    assert_eq!(bound, host, "kernel bindings vs gpu::layout::BINDINGS");
}
