//! The host/kernel contract, written once: precision, storage slots, codes and the `Control`
//! uniform. The kernel does not declare any of it: `prelude` generates the WGSL declarations
//! from the Rust definitions below (and the model's parameter table) and
//! `kernel::shader_source` prepends them to the pieces of `shaders/`, so a slot renumbered
//! here moves on both sides at once.
//! tests/shaders.rs parses the generated source with naga and checks every constant's value
//! and the `Control` member offsets against this file.
//!
//! Per-point buffers are structures of arrays: slot `s` of point `i` of `n` sits at
//! `s * n + i` (see [`at`]), so neighbouring invocations touch neighbouring words.

use crate::classify;
use crate::config::Precision;
use crate::method;
use crate::model::{Mode, N_PARAMS, Param, Params};
use std::fmt::Write;

/// A commented group of u32 constants of the prelude.
struct Group {
    heading: &'static str,
    items: &'static [(&'static str, u32)],
}

/// Declares `pub const NAME: u32` items and the `Group` that lists them (by their Rust names,
/// so the WGSL names cannot drift from the host's).
macro_rules! u32_group {
    ($group:ident, $heading:literal { $( $(#[$m:meta])* $name:ident = $value:expr; )* }) => {
        $( $(#[$m])* pub const $name: u32 = $value; )*
        const $group: Group = Group {
            heading: $heading,
            items: &[$((stringify!($name), $name)),*],
        };
    };
}

/// The kernel's bindings (group 0), each with the name of the shader's variable it feeds;
/// tests/shaders.rs checks every pair against the `@binding` attributes of the kernel.
pub const B_CONTROL: u32 = 0;
pub const B_CONSTS: u32 = 1;
pub const B_PVALS: u32 = 2;
pub const B_YS: u32 = 3;
pub const B_US: u32 = 4;
pub const B_SAMPLES: u32 = 5;
pub const B_RING: u32 = 6;
pub const B_UTAB: u32 = 7;
pub const BINDINGS: [(&str, u32); 8] = [
    ("ctl", B_CONTROL),
    ("consts", B_CONSTS),
    ("pvals", B_PVALS),
    ("ys", B_YS),
    ("us", B_US),
    ("samples", B_SAMPLES),
    ("ring", B_RING),
    ("utab", B_UTAB),
];

u32_group!(DISPATCH, "Invocations per workgroup (`@workgroup_size`)." {
    WORKGROUP = 64;
});

u32_group!(MODES, "Motion modes, as model::Mode." {
    MODE_SLIP_POS = Mode::SlipPos as u32;
    MODE_SLIP_NEG = Mode::SlipNeg as u32;
    MODE_STICK = Mode::Stick as u32;
    MODE_LOCK_POS = Mode::LockPos as u32;
    MODE_LOCK_NEG = Mode::LockNeg as u32;
});

u32_group!(EVENTS, "Event kinds, as method::EV_*." {
    EV_NONE = method::EV_NONE;
    EV_IMPACT_POS = method::EV_IMPACT_POS;
    EV_IMPACT_NEG = method::EV_IMPACT_NEG;
    EV_REVERSAL = method::EV_REVERSAL;
    EV_RELEASE_POS = method::EV_RELEASE_POS;
    EV_RELEASE_NEG = method::EV_RELEASE_NEG;
});

u32_group!(LIMITS, "Limits shared with the CPU twin." {
    /// Blocks of the exponent's batch-means error (classify::BLOCKS).
    BLOCKS = classify::BLOCKS;
    /// Iteration cap of the root finder.
    MAX_ROOT_ITERS = method::MAX_ROOT_ITERS;
    /// Longest period the detector finds (bits of U_DET_LO/HI, values of its ring).
    MAX_PERIOD = classify::MAX_PERIOD as u32;
    /// Past section values in the ring (the detector reads the last MAX_PERIOD).
    TAIL = classify::TAIL as u32;
    /// Components of a state (y1..y4, one vec4).
    STATE_DIM = 4;
    /// Newton iterations at most (cycles::NEWTON_ITERS).
    NEWTON_ITERS = crate::cycles::NEWTON_ITERS;
});

u32_group!(NEWTON, "Newton's method on the device (newton.wgsl): U_NEWTON_DONE, U_NEWTON_PHASE." {
    /// Still iterating (or paused, or cut short: U_TRUNCATED).
    NEWTON_OPEN = 0;
    /// The next step ends the trial; the host's step decides it.
    NEWTON_HANDED = 1;
    /// As NEWTON_HANDED, the iterate converged and returns to itself after no proper divisor
    /// of the period (cycles.rs `least_return` found none): the host need not look again.
    NEWTON_NO_DIVISOR = 2;
    /// Phases: a flow of the iteration, or the least-period pass of a converged iterate.
    PHASE_FLOW = 0;
    PHASE_LEAST = 1;
});

u32_group!(US, "Slots of `us`, u32 per point: us[slot * n_points + i]." {
    U_MODE = 0;
    U_IMPACTS = 1;
    /// Impacts during the sampled periods (the class needs them, not the transient's).
    U_SAMPLE_IMPACTS = 2;
    U_STICKS = 3;
    U_LOCKS = 4;
    U_OVERFLOWS = 5;
    U_NONFINITE = 6;
    /// Period detector: section values pushed, and the 64 bits of still possible periods.
    U_DET_COUNT = 7;
    U_DET_LO = 8;
    U_DET_HI = 9;
    /// Set when the driver cut a loop short (llvmpipe limits the loop iterations of one
    /// invocation); the host then rejects the run instead of returning a wrong answer.
    U_TRUNCATED = 10;
    /// The Lyapunov tangent vector overflowed: the point has no exponent.
    U_TAN_BAD = 11;
    /// Steps that ended in slip against the mode's direction (Diagnostics::wrong_slips).
    U_WRONG_SLIPS = 12;
    /// Periods a flow of Newton's method has left (flows.wgsl).
    U_FLOW_LEFT = 13;
    U_SLOTS = 14;
    /// Newton's method on the device (newton.wgsl), beyond the kernel's slots: the period of
    /// the cycle sought, the iterations done, the iterate's mode, NEWTON_* once the iteration
    /// is handed back to the host (its next step ends it: cycles.rs `Refine::step` decides),
    /// the iterations after which this call pauses it, the phase (a flow, or the least-period
    /// pass of a converged iterate), and the pass's periods done and mode.
    U_NEWTON_PERIOD = U_SLOTS;
    U_NEWTON_ITERS = U_SLOTS + 1;
    U_ITER_MODE = U_SLOTS + 2;
    U_NEWTON_DONE = U_SLOTS + 3;
    U_NEWTON_PAUSE = U_SLOTS + 4;
    U_NEWTON_PHASE = U_SLOTS + 5;
    U_LEAST_DONE = U_SLOTS + 6;
    U_LEAST_MODE = U_SLOTS + 7;
    U_NEWTON_SLOTS = U_SLOTS + 8;
});

// The last TAIL section values sit at slots 0..TAIL (value k at k % TAIL).
u32_group!(RING, "Slots of `ring`, F per point: past values, their range, the log sum." {
    /// Range of the values pushed so far (the detector's tolerance scales with it).
    R_LO = TAIL;
    R_HI = TAIL + 1;
    /// Sum of the logs of the tangent vector's growth per sampled period (Lyapunov estimate).
    R_LOG_SUM = TAIL + 2;
    /// classify::Growth: the current block's log sum, the blocks' running mean and Welford M2.
    R_BLOCK = TAIL + 3;
    R_BLOCK_MEAN = TAIL + 4;
    R_BLOCK_M2 = TAIL + 5;
    /// classify::Birkhoff: weighted sum and weight sum of the current half, the two averages.
    R_WB_NUM = TAIL + 6;
    R_WB_DEN = TAIL + 7;
    R_WB_FIRST = TAIL + 8;
    R_WB_SECOND = TAIL + 9;
    /// Impact speeds: their sum per sampled period (a running mean over the periods), and the
    /// largest since sampling started (method::Diagnostics).
    R_IMPACT_SPEED_SUM = TAIL + 10;
    R_IMPACT_SPEED_MAX = TAIL + 11;
    /// Energy dissipated by impacts and by friction, and grid steps stuck, per sampled period
    /// (running means over the periods; method::Diagnostics holds their sums).
    R_LOSS_IMPACTS = TAIL + 12;
    R_LOSS_FRICTION = TAIL + 13;
    R_STUCK = TAIL + 14;
    R_SLOTS = TAIL + 15;
});

u32_group!(YS, "Slots of `ys`, F per point: state and Lyapunov tangent, STATE_DIM slots each." {
    Y_MAIN = 0;
    Y_TAN = Y_MAIN + STATE_DIM;
    Y_SLOTS = Y_TAN + STATE_DIM;
    /// A flow of Newton's method (flows.wgsl): the state and the four tangent vectors.
    Y_FLOW_SLOTS = Y_TAN + 4 * STATE_DIM;
    /// Newton's method (newton.wgsl): the flow, then the iterate, the residual of the last
    /// iteration and the one before it (cycles.rs `Refine`'s `st`, `out.residual`, `before`).
    Y_ITER = Y_FLOW_SLOTS;
    Y_RESIDUAL = Y_ITER + STATE_DIM;
    Y_BEFORE = Y_RESIDUAL + 1;
    /// The least-period pass's state (newton.wgsl).
    Y_LEAST = Y_BEFORE + 1;
    Y_NEWTON_SLOTS = Y_LEAST + STATE_DIM;
});

// Base parameters in the order of the kernel's Params, method constants, then the forcing
// table: (cos, sin) at phases 2*pi*j/(2N), j = 0..2N.
u32_group!(CONSTS, "Slots of `consts`, F shared by all points." {
    /// The model's parameters, in the order of `model::Params::FIELDS`.
    C_PARAMS = 0;
    /// Relative speed below which an impact ends in co-motion.
    C_ZENO = C_PARAMS + N_PARAMS as u32;
    /// Root finder tolerance in theta, 16 epsilon of F.
    C_TOL = C_ZENO + 1;
    C_PERIOD_TOL = C_ZENO + 2;
    /// Forcing phase of one RK4 step, 2 pi / N.
    C_DPHI = C_ZENO + 3;
    /// Norm below which the Lyapunov tangent vector counts as collapsed (eps^2 of F).
    C_TAN_FLOOR = C_ZENO + 4;
    /// cos and sin of half a step's forcing phase (`method::half_step`).
    C_HALF_COS = C_ZENO + 5;
    C_HALF_SIN = C_ZENO + 6;
    /// Start of the forcing table, at an even slot (a vec2<F> per entry).
    C_TABLE = (C_ZENO + 8) & !1;
});

/// Bytes of `utab`, the uniform copy of the forcing table's step ends: WebGPU's minimum (and
/// wgpu's default) max_uniform_buffer_binding_size, so every adapter can bind it.
pub const UTAB_BYTES: u64 = 65536;

/// Entries of `utab` in a precision (one `vec4<F>` each: the forcing at step end k and at the
/// middle of step k + 1); jobs with fewer steps per period than this can use it.
pub fn utab_len(precision: Precision) -> u32 {
    let f = match precision {
        Precision::F32 => 4,
        Precision::F64 => 8,
    };
    (UTAB_BYTES / (4 * f)) as u32
}

/// `Control.vary0/1/2` of a point set with fewer varying parameters.
pub const VARY_NONE: u32 = 255;

/// Kernel name of a parameter's code (`Param::code`), after the field it sets in the kernel's
/// Params (exhaustive, so a new parameter cannot be forgotten here).
fn vary_name(p: Param) -> String {
    format!("VARY_{}", p.field().unwrap_or("lambda").to_uppercase())
}

const GROUPS: [Group; 9] = [
    DISPATCH, MODES, EVENTS, LIMITS, NEWTON, US, RING, YS, CONSTS,
];

/// Declares the `Control` uniform (u32 members only, so repr(C) and the WGSL uniform layout
/// agree member by member) and the list of its members for the prelude and the tests.
macro_rules! control {
    ($( $(#[$m:meta])* $field:ident, )*) => {
        /// Uniform control block of one dispatch.
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct Control {
            $( $(#[$m])* pub $field: u32, )*
        }

        impl Control {
            /// Member names and byte offsets, in declaration order.
            pub const MEMBERS: &[(&str, usize)] =
                &[$((stringify!($field), std::mem::offset_of!(Control, $field))),*];
        }
    };
}

control! {
    /// Points of this batch.
    n_points,
    /// RK4 steps per forcing period.
    steps,
    /// Periods of this dispatch.
    periods,
    /// Index of the first period of this dispatch.
    period0,
    /// Periods before sampling starts, and sampled periods.
    transient,
    samples,
    /// Whether samples are stored (bifurcation) or only classified.
    store,
    max_events,
    /// Varying parameters (0..3) and their codes (VARY_*).
    n_vary,
    vary0,
    vary1,
    vary2,
    /// Naive impact handling (checked after the step) instead of event location.
    naive,
    /// Invocations per row of a 2-D grid (dispatches beyond the per-dimension limit).
    row,
    /// Whether the Lyapunov tangent vector runs (in the sampled periods).
    lyap,
    /// Pads the uniform to a multiple of 16 bytes.
    pad,
}

/// Index of slot `slot` of point `i` among `n` (structure of arrays).
pub fn at(slot: u32, n: usize, i: usize) -> usize {
    slot as usize * n + i
}

/// Every generated u32 constant, name and value.
pub fn constants() -> Vec<(String, u32)> {
    let fixed = GROUPS
        .iter()
        .flat_map(|g| g.items.iter().map(|&(n, v)| (n.to_string(), v)));
    let vary = Param::ALL.iter().map(|&p| (vary_name(p), p.code()));
    fixed
        .chain(vary)
        .chain([("VARY_NONE".to_string(), VARY_NONE)])
        .collect()
}

/// WGSL name of a precision (the kernel's `F`).
fn wgsl_type(precision: Precision) -> &'static str {
    match precision {
        Precision::F32 => "f32",
        Precision::F64 => "f64",
    }
}

/// WGSL declarations of the contract, prepended to the kernel.
pub fn prelude(precision: Precision) -> String {
    let mut s = contract(precision);
    write_params(&mut s).expect("writing to a String cannot fail");
    s
}

/// The contract without the model's parameters (the precision, the slots and codes,
/// `Control`): what rung 0 of the ladder, which has its parameters as literals, compiles after.
pub fn contract(precision: Precision) -> String {
    let mut s = String::new();
    write_contract(&mut s, precision).expect("writing to a String cannot fail");
    s
}

fn write_contract(s: &mut String, precision: Precision) -> std::fmt::Result {
    writeln!(
        s,
        "// Generated by the host from src/gpu/layout.rs; edit there, not here."
    )?;
    writeln!(
        s,
        "\n// Precision: f32, or f64 where the adapter has SHADER_F64."
    )?;
    writeln!(s, "alias F = {};", wgsl_type(precision))?;
    writeln!(
        s,
        "\n// Entries of the uniform copy of the forcing table (UTAB_BYTES / 16 / size of F)."
    )?;
    writeln!(s, "const UTAB_LEN: u32 = {}u;", utab_len(precision))?;
    for g in &GROUPS {
        writeln!(s, "\n// {}", g.heading)?;
        for (name, value) in g.items {
            writeln!(s, "const {name}: u32 = {value}u;")?;
        }
    }
    writeln!(
        s,
        "\n// Codes of per-point parameters, model::Param::code (LAMBDA sets fs and fk)."
    )?;
    for p in Param::ALL {
        writeln!(s, "const {}: u32 = {}u;", vary_name(p), p.code())?;
    }
    writeln!(s, "const VARY_NONE: u32 = {VARY_NONE}u;")?;
    writeln!(
        s,
        "\n// Newton's convergence: max |P^n(x) - x| below this times max(1, |x|) (cycles.rs)."
    )?;
    writeln!(
        s,
        "const NEWTON_TOL: F = F({:e});",
        crate::cycles::NEWTON_TOL
    )?;
    writeln!(s, "\n// Uniform control block of one dispatch.")?;
    writeln!(s, "struct Control {{")?;
    for (name, _) in Control::MEMBERS {
        writeln!(s, "    {name}: u32,")?;
    }
    writeln!(s, "}}")
}

/// The model's parameters as the kernel sees them (model::Params, from the parameter table):
/// the struct, one accessor per field, the load from `consts` and `set_param`, the twin of
/// `Param::set`. Scalars rather than an array, so that the per-point override does not force
/// every access through dynamically indexed memory.
fn write_params(s: &mut String) -> std::fmt::Result {
    let fields = Params::<f64>::FIELDS;
    writeln!(s, "\n// The model's parameters (model::Params).")?;
    writeln!(s, "struct Params {{")?;
    for f in fields {
        writeln!(s, "    {f}: F,")?;
    }
    writeln!(s, "}}")?;
    for f in fields {
        writeln!(s, "fn {f}() -> F {{ return prm.{f}; }}")?;
    }
    let loads: Vec<String> = (0..fields.len())
        .map(|i| format!("consts[C_PARAMS + {i}u]"))
        .collect();
    writeln!(
        s,
        "fn load_params() -> Params {{ return Params({}); }}",
        loads.join(", ")
    )?;
    writeln!(
        s,
        "// model::Param::set.\nfn set_param(code: u32, v: F) {{\n    switch code {{"
    )?;
    for &p in &Param::ALL {
        let body = match p.field() {
            Some(f) => format!("prm.{f} = v;"),
            // Lambda: the Coulomb coefficient is both Stribeck levels.
            None => "prm.fs = v; prm.fk = v;".to_string(),
        };
        writeln!(s, "        case {}: {{ {body} }}", vary_name(p))?;
    }
    writeln!(s, "        default: {{}}\n    }}\n}}\n")
}
