//! Every shader parses and validates with naga, in f32 and in f64, without a GPU; and the
//! kernel holds the host/kernel contract of src/gpu/layout.rs as the host sees it.

use naga::valid::{Capabilities, ValidationFlags, Validator};
use rattle::config::Precision;
use rattle::gpu::layout::{self, Control};
use rattle::gpu::{BARE_SHADER, bare_source, shader_source};
use rattle::method::bare::BareConsts;

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

/// Every piece of WGSL: the kernel's, rung 0's and Newton's.
fn pieces() -> impl Iterator<Item = (&'static str, &'static str)> {
    rattle::gpu::SHADER
        .into_iter()
        .chain([BARE_SHADER])
        .chain(rattle::gpu::FLOWS_SHADER)
}

#[test]
fn flows_kernel_validates_in_f32_and_f64() {
    use rattle::gpu::flows_source;
    validate(&flows_source(Precision::F32), Capabilities::empty())
        .unwrap_or_else(|e| panic!("{e}"));
    let src = flows_source(Precision::F64);
    assert!(src.contains("const TANGENTS: u32 = 4u;") && !src.contains("fn main("));
    assert!(src.contains("fn flows(") && src.contains("fn newton("));
    validate(&src, Capabilities::FLOAT64).unwrap_or_else(|e| panic!("{e}"));
}

/// Rung 0's constants at the paper's parameters, N = 256.
fn bare_consts() -> BareConsts<f64> {
    BareConsts::new(&rattle::model::Params::paper(1.5), 256)
}

#[test]
fn bare_kernel_validates_in_f32_and_f64() {
    validate(
        &bare_source(Precision::F32, &bare_consts()),
        Capabilities::empty(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let src = bare_source(Precision::F64, &bare_consts());
    validate(&src, Capabilities::FLOAT64).unwrap_or_else(|e| panic!("{e}"));
    assert!(validate(&src, Capabilities::empty()).is_err());
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
        .iter()
        .flat_map(|(_, text)| text.lines())
        .map(|l| l.split("//").next().unwrap().trim())
        .collect();
    let declares = |start: &str| code.iter().any(|l| l.starts_with(start));
    assert!(!declares("alias F"), "the kernel declares its precision");
    assert!(!declares("struct Control"), "the kernel declares Control");
    assert!(
        !declares("struct Params"),
        "the kernel declares the model's parameters"
    );
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
                .find(|(_, c)| c.name.as_deref() == Some(name.as_str()))
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
            .filter(|c| c.0.starts_with(prefix) && c.0 != count && !c.0.ends_with("_SLOTS"))
            .map(|c| c.1)
            .collect();
        slots.sort();
        let n = slots.len();
        slots.dedup();
        assert_eq!(slots.len(), n, "{prefix}* slots repeat");
        assert!(slots.iter().all(|&s| s < total), "{prefix}* beyond {count}");
    };
    // Newton's slots (newton.wgsl) follow the kernel's, which its buffers hold.
    group("U_", "U_NEWTON_SLOTS");
    group("Y_", "Y_NEWTON_SLOTS");
    assert_eq!(layout::U_NEWTON_PERIOD, layout::U_SLOTS);
    assert_eq!(layout::Y_ITER, layout::Y_FLOW_SLOTS);
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

/// The Rust functions of `path` (`fn name`, or `Type::name` for a method of `impl Type`) in
/// the order they are written, each with its byte offset.
fn rust_functions(path: &str) -> Vec<(String, usize)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut out = Vec::new();
    let mut owner: Option<String> = None;
    let mut at = 0;
    for line in text.lines() {
        let t = line.trim_start();
        if line.starts_with("impl") {
            // `impl<F: Real> Growth<F> {`, `impl Birkhoff {`: the type is the last word
            // before `{` or `<` that is not a trait of `for`.
            let head = line.split('{').next().unwrap_or("");
            let head = head.rsplit(" for ").next().unwrap_or(head);
            let words: Vec<&str> = head
                .split(|c: char| !c.is_alphanumeric() && c != '_')
                .collect();
            owner = words
                .iter()
                .skip(1)
                .find(|w| w.chars().next().is_some_and(|c| c.is_uppercase()) && **w != "Real")
                .map(|w| w.to_string());
        } else if !line.starts_with([' ', '/', '#']) && !line.is_empty() {
            // Any other item at the left margin ends the impl block.
            owner = None;
        }
        let f = t
            .strip_prefix("pub(crate) fn ")
            .or_else(|| t.strip_prefix("pub(super) fn "))
            .or_else(|| t.strip_prefix("pub fn "))
            .or_else(|| t.strip_prefix("fn "))
            .or_else(|| t.strip_prefix("pub const fn "));
        if let Some(f) = f {
            let name: String = f
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            out.push((name.clone(), at));
            if let Some(o) = &owner {
                out.push((format!("{o}::{name}"), at));
            }
        }
        at += line.len() + 1;
    }
    out
}

/// The kernel's pieces and their Rust twins: every function of a piece has a twin of the same
/// name (or the one its `// twin:` line names) in the piece's twin file, and the twins come in
/// the same order; a function with no twin is declared `// shader-only:` with the reason.
/// The functions are those naga finds in the whole kernel, so none escapes the check.
#[test]
fn every_shader_function_has_its_rust_twin_in_the_same_order() {
    let bare = bare_source(Precision::F32, &bare_consts());
    let kernel: Vec<String> = [parse(&shader_source(Precision::F32)), parse(&bare)]
        .iter()
        .flat_map(|module| {
            module
                .functions
                .iter()
                .filter_map(|(_, f)| f.name.clone())
                .chain(module.entry_points.iter().map(|e| e.name.clone()))
                .collect::<Vec<_>>()
        })
        .collect();
    let generated = rattle::gpu::layout::prelude(Precision::F32);
    let mut seen = Vec::new();
    for (piece, text) in pieces() {
        let lines: Vec<&str> = text.lines().collect();
        let twin_file = lines[0]
            .strip_prefix("// twin: ")
            .unwrap_or_else(|| panic!("{piece}: the first line names no twin"));
        let rust = (twin_file.starts_with("src/")).then(|| rust_functions(twin_file));
        let mut last = 0;
        for (i, line) in lines.iter().enumerate() {
            let Some(rest) = line.strip_prefix("fn ") else {
                continue;
            };
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            seen.push(name.clone());
            // The comment block above the function.
            let above: Vec<&str> = lines[..i]
                .iter()
                .rev()
                .take_while(|l| l.starts_with("//") || l.starts_with('@'))
                .copied()
                .collect();
            if above.iter().any(|l| l.starts_with("// shader-only: ")) {
                continue;
            }
            let rust = rust.as_ref().unwrap_or_else(|| {
                panic!("{piece}: `{name}` has no twin file and is not declared shader-only")
            });
            let twin = above
                .iter()
                .find_map(|l| l.strip_prefix("// twin: "))
                .map_or(name.clone(), str::to_string);
            // The first twin after the previous function's: the pieces follow their files.
            assert!(
                rust.iter().any(|(n, _)| *n == twin),
                "{piece}: `{name}` has no twin `{twin}` in {twin_file}"
            );
            last = rust
                .iter()
                .find(|(n, at)| *n == twin && *at >= last)
                .unwrap_or_else(|| {
                    panic!("{piece}: `{name}` is out of the order of `{twin}` in {twin_file}")
                })
                .1;
        }
    }
    for name in &kernel {
        let in_prelude = generated.contains(&format!("fn {name}("));
        assert!(
            in_prelude || seen.contains(name),
            "naga finds `{name}`, which no piece declares at the start of a line"
        );
    }
}

/// Comments of the pieces cite Rust files that exist.
#[test]
fn shader_comments_cite_files_that_exist() {
    for (piece, text) in pieces() {
        for word in text.split(|c: char| c.is_whitespace() || "`(),:;".contains(c)) {
            if word.ends_with(".rs") {
                let found = std::path::Path::new(word).exists()
                    || std::path::Path::new("src").join(word).exists()
                    || std::path::Path::new("src/method").join(word).exists()
                    || std::path::Path::new("src/gpu").join(word).exists();
                assert!(found, "{piece} cites {word}, which does not exist");
            }
        }
    }
}
