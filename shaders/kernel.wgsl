// twin: none (the kernel's bindings and per-invocation state; the host side is src/gpu/layout.rs)
// The integration method of src/method/, one invocation per parameter point, in pieces named
// like their Rust twins: model.wgsl (src/model.rs), events.wgsl (src/method/events.rs),
// method.wgsl (src/method/mod.rs), tangent.wgsl (src/method/tangent.rs), detector.wgsl
// (src/classify.rs) and main.wgsl (the entry point). Each piece holds its twin's functions
// with the same names in the same order (tests/shaders.rs checks it); a function with no
// Rust twin says why. Read the Rust side for the reasoning; comments here only note what
// differs in form.
//
// The host prepends `alias F = f32;` or `alias F = f64;`, the constants (MODE_*, EV_*, slots
// U_*, R_*, Y_*, C_*, codes VARY_*), the `Control` uniform and the parameters (`Params`, their
// accessors and `set_param`), all generated from src/gpu/layout.rs and src/model.rs, then
// concatenates the pieces (src/gpu/kernel.rs `shader_source`). In F only + - * / sqrt,
// comparisons and conversions are used (no cos/exp: unreliable in f64 on some drivers): the
// forcing comes from a host-computed table, and abs/min/max are selects.

// Rungs of the kernel ladder (`rattle bench --ladder`): each piece of the kernel can be left
// out at pipeline creation, so that a rung is compiled without the pieces above it (on
// llvmpipe the code present costs even where it does not run). The production kernel has
// every piece (the defaults); without LADDER_QUIET every step goes through `step`.
override LADDER_FINITE: bool = true;
override LADDER_DETECTOR: bool = true;
override LADDER_GUARDS: bool = true;
override LADDER_EVENTS: bool = true;
override LADDER_QUIET: bool = true;

// Every point of the job has Coulomb friction (l1 = l2 = 0, fs = fk): the law is fk, bit for
// bit for any finite slip speed, without the division the general law needs in every stage.
override COULOMB: bool = false;

// The job estimates the largest Lyapunov exponent: one tangent vector follows the state through
// its RK4 stages and events (tangent.rs `Leading`). Off, none of its code is compiled in, so the
// plain kernel computes and costs what it did without it.
override TANGENT: bool = false;

// The quiet loop reads the step ends from `utab` (set by the host on CPU adapters, for jobs
// with fewer than UTAB_LEN steps per period).
override UNIFORM_TABLE: bool = false;
@group(0) @binding(0) var<uniform> ctl: Control;
@group(0) @binding(1) var<storage, read> consts: array<F>;
@group(0) @binding(2) var<storage, read> pvals: array<F>;
@group(0) @binding(3) var<storage, read_write> ys: array<F>;
@group(0) @binding(4) var<storage, read_write> us: array<u32>;
@group(0) @binding(5) var<storage, read_write> samples: array<F>;
@group(0) @binding(6) var<storage, read_write> ring: array<F>;

// The forcing table's entries 2k and 2k + 1 (step end k, middle of step k + 1) in a uniform
// buffer, read where UNIFORM_TABLE: on llvmpipe a storage read at a per-lane index runs a loop
// over the lanes, a uniform read is one gather instruction. On GPUs a uniform read at
// divergent indices is serialized, so there the table stays in storage.
@group(0) @binding(7) var<uniform> utab: array<vec4<F>, UTAB_LEN>;
var<private> prm: Params;
var<private> h: F;
var<private> dphi: F;
var<private> zeno: F;
var<private> tol: F;

// model.rs `inv_mu`, `inv_one_plus_mu`: the field multiplies where it would divide.
var<private> inv_mu: F;
var<private> inv_1pmu: F;

// cos and sin of half a step's forcing phase (events.rs `half_step`).
var<private> half: vec2<F>;

struct PointState {
    y: vec4<F>,
    mode: u32,
    impacts: u32,
    sticks: u32,
    locks: u32,
    overflows: u32,
    // Diagnostics::wrong_slips: steps ending in slip against the mode's direction.
    wrong_slips: u32,
    nonfinite: u32,
    // Sum of the impact speeds over the current period, and the largest since sampling started
    // (Diagnostics::impact_speed; main.wgsl adds the period's sums to the totals).
    impact_speed: vec2<F>,
    // Energy dissipated by impacts and by friction, and grid steps stuck, over the current
    // period (Diagnostics::dissipated, stuck_steps).
    loss: vec2<F>,
    stuck: F,
}
var<private> st: PointState;

// shader-only: abs, max and min as selects (WGSL's builtins on f64 are not on every driver).
fn fabs(x: F) -> F { return select(-x, x, x >= F(0.0)); }
// shader-only: as fabs.
fn fmax(a: F, b: F) -> F { return select(b, a, a > b); }
// shader-only: as fabs.
fn fmin(a: F, b: F) -> F { return select(b, a, a < b); }
// shader-only: the largest |component| (nalgebra's `amax` on the host).
fn amax4(v: vec4<F>) -> F { return fmax(fmax(fabs(v.x), fabs(v.y)), fmax(fabs(v.z), fabs(v.w))); }

// shader-only: buffer access (the host side is src/gpu/layout.rs).
// A vector in `ys` from slot `base` on (Y_MAIN, Y_TAN + k STATE_DIM).
fn load_y(base: u32, i: u32) -> vec4<F> {
    let n = ctl.n_points;
    return vec4<F>(ys[base * n + i], ys[(base + 1u) * n + i], ys[(base + 2u) * n + i],
                   ys[(base + 3u) * n + i]);
}

// shader-only: buffer access.
fn store_y(base: u32, i: u32, y: vec4<F>) {
    let n = ctl.n_points;
    ys[base * n + i] = y.x;
    ys[(base + 1u) * n + i] = y.y;
    ys[(base + 2u) * n + i] = y.z;
    ys[(base + 3u) * n + i] = y.w;
}

// shader-only: Integrator::new computes these from the point's parameters `prm`.
// The per-invocation constants of the point's parameters.
fn derive_constants() {
    zeno = consts[C_ZENO];
    tol = consts[C_TOL];
    dphi = consts[C_DPHI];
    half = vec2<F>(consts[C_HALF_COS], consts[C_HALF_SIN]);
    h = dphi / eta();
    inv_mu = F(1.0) / mu();
    inv_1pmu = F(1.0) / (F(1.0) + mu());
}
