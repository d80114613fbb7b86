//! The kernel: its source and its compiled pipelines.

use super::layout::{self, B_CONSTS, B_CONTROL, B_PVALS, B_RING, B_SAMPLES, B_US, B_UTAB, B_YS};
use crate::config::Precision;
use crate::method::bare::BareConsts;
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

/// The kernel as written, in pieces named like their Rust twins (file name, text). It does not
/// compile alone: the precision alias, the constants, `Control` and the model's parameters
/// come from the prelude (see [`shader_source`]).
pub const SHADER: [(&str, &str); 7] = [
    ("kernel.wgsl", include_str!("../../shaders/kernel.wgsl")),
    ("model.wgsl", include_str!("../../shaders/model.wgsl")),
    ("events.wgsl", include_str!("../../shaders/events.wgsl")),
    ("method.wgsl", include_str!("../../shaders/method.wgsl")),
    ("tangent.wgsl", include_str!("../../shaders/tangent.wgsl")),
    ("detector.wgsl", include_str!("../../shaders/detector.wgsl")),
    ("main.wgsl", include_str!("../../shaders/main.wgsl")),
];

/// Rung 0 of the ladder, the bare RK4 step (file name, text); it compiles after the prelude
/// and the literal block of [`bare_source`].
pub const BARE_SHADER: (&str, &str) = ("bare.wgsl", include_str!("../../shaders/bare.wgsl"));

/// The bare kernel's source in a precision: the generated contract of `layout` (without the
/// model's parameters), the constants of `k` as literals (`BARE_*`), then `shaders/bare.wgsl`.
pub fn bare_source(precision: Precision, k: &BareConsts<f64>) -> String {
    let mut src = layout::contract(precision);
    src += "\n// Rung 0's constants, literals of the run's base parameters (method/bare.rs).\n";
    for (name, v) in [
        ("BARE_B1", k.b1),
        ("BARE_DELTA", k.delta),
        ("BARE_T", k.t),
        ("BARE_INV_MU", k.inv_mu),
        ("BARE_ETA", k.eta),
        ("BARE_DPHI", k.dphi),
    ] {
        src += &format!("const {name}: F = F({v:?});\n");
    }
    src += &format!(
        "const BARE_HALF: vec2<F> = vec2<F>(F({:?}), F({:?}));\n",
        k.half[0], k.half[1]
    );
    src += &format!("\n// ---- shaders/{} ----\n", BARE_SHADER.0);
    src += BARE_SHADER.1;
    src
}

/// The kernel source in a precision: the generated contract of `layout`, then the body.
/// The one way to get the kernel text, for the runner and the tests alike.
pub fn shader_source(precision: Precision) -> String {
    let mut src = layout::prelude(precision);
    for (name, text) in SHADER {
        src += &format!("\n// ---- shaders/{name} ----\n");
        src += text;
    }
    src
}

/// Rungs of the kernel ladder (`rattle bench --ladder`): the kernel compiled with its pieces
/// added one at a time (pipeline-overridable constants `LADDER_*` in the shader), to find where
/// the speed goes. `Full` is the production kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Rung {
    /// Rung 0: the bare RK4 step, a kernel of its own (`shaders/bare.wgsl`): the Coulomb field
    /// with the friction sign held, parameters as literals, the forcing rotated, no events.
    Bare,
    /// RK4 steps in the current mode with the forcing table, nothing else.
    Table,
    /// + the non-finite test after each step.
    Finite,
    /// + stroboscopic samples and the period detector.
    Detector,
    /// + the tangent vector of the Lyapunov estimate (compiled in when the job asks for the
    ///   exponent, as in production).
    Tangent,
    /// + the event guards and their brackets (a bracketed event ends the step as an overflow).
    Guards,
    /// + root refinement and event application, all of it in every step.
    Events,
    /// + quiet steps out of line (only steps whose guards may reach zero go through the
    ///   event code): the production kernel.
    #[default]
    Full,
}

impl Rung {
    pub const ALL: [Rung; 8] = [
        Rung::Bare,
        Rung::Table,
        Rung::Finite,
        Rung::Detector,
        Rung::Tangent,
        Rung::Guards,
        Rung::Events,
        Rung::Full,
    ];

    pub fn describe(self) -> &'static str {
        match self {
            Rung::Bare => "0: bare RK4 step (minimal kernel)",
            Rung::Table => "RK4 step, forcing table",
            Rung::Finite => "+ non-finite test",
            Rung::Detector => "+ samples, period detector",
            Rung::Tangent => "+ tangent (with the exponent)",
            Rung::Guards => "+ event guards, brackets",
            Rung::Events => "+ refinement, events in every step",
            Rung::Full => "+ quiet steps out of line (production)",
        }
    }

    /// Values of the shader's `LADDER_*` constants, `COULOMB` (friction law of every point
    /// of the job is Coulomb's: a kernel without the general law's division), `TANGENT` (the
    /// job estimates the exponent: a kernel without it has none of the tangent's code, which
    /// on llvmpipe costs even where it does not run) and `UNIFORM_TABLE` (the quiet loop reads
    /// the forcing from the uniform copy of the table).
    fn constants(self, v: Variant) -> [(&'static str, f64); 8] {
        let on = |r: Rung| if self as u8 >= r as u8 { 1.0 } else { 0.0 };
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        [
            ("LADDER_FINITE", on(Rung::Finite)),
            ("LADDER_DETECTOR", on(Rung::Detector)),
            ("LADDER_GUARDS", on(Rung::Guards)),
            ("LADDER_EVENTS", on(Rung::Events)),
            ("LADDER_QUIET", on(Rung::Full)),
            ("COULOMB", flag(v.coulomb)),
            ("TANGENT", flag(v.tangent) * on(Rung::Tangent)),
            ("UNIFORM_TABLE", flag(v.uniform_table)),
        ]
    }
}

/// What a job compiles into its kernel besides the precision and the rung.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub(super) struct Variant {
    /// Every point of the job has Coulomb friction.
    pub(super) coulomb: bool,
    /// The tangent vector of the Lyapunov exponent.
    pub(super) tangent: bool,
    /// The quiet loop reads `utab` (CPU adapters, jobs that fit it).
    pub(super) uniform_table: bool,
}

/// Compiled kernels per precision, rung and variant, built on first use
/// (continuation runs many small jobs and compiles once; a run that never asks for f64 never
/// compiles it).
#[derive(Default)]
pub(super) struct Kernels {
    pipelines: Mutex<HashMap<(Precision, Rung, Variant, String), wgpu::ComputePipeline>>,
    /// One bind group layout for every pipeline (an automatic layout belongs to its pipeline
    /// alone), so that a batch's bind group serves the kernel with the tangent and the one
    /// without it, which runs the transient.
    layout: OnceLock<(wgpu::BindGroupLayout, wgpu::PipelineLayout)>,
}

/// The kernel's bindings: the control uniform, the read-only constants and per-point
/// parameters, then the per-point state, counters, samples and ring, then the uniform copy of
/// the forcing table.
fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let storage = |read_only| wgpu::BufferBindingType::Storage { read_only };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("integrate"),
        entries: &[
            entry(B_CONTROL, wgpu::BufferBindingType::Uniform),
            entry(B_CONSTS, storage(true)),
            entry(B_PVALS, storage(true)),
            entry(B_YS, storage(false)),
            entry(B_US, storage(false)),
            entry(B_SAMPLES, storage(false)),
            entry(B_RING, storage(false)),
            entry(B_UTAB, wgpu::BufferBindingType::Uniform),
        ],
    })
}

impl Kernels {
    /// The pipeline of `rung` for the job `spec` describes (rung 0 compiles the job's base
    /// parameters in, and is cached per parameter set).
    pub(super) fn get(
        &self,
        device: &wgpu::Device,
        spec: &crate::spec::RunSpec,
        rung: Rung,
        variant: Variant,
    ) -> wgpu::ComputePipeline {
        let precision = spec.precision;
        let (_, layout) = self.layout.get_or_init(|| {
            let group = bind_group_layout(device);
            let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("integrate"),
                bind_group_layouts: &[Some(&group)],
                immediate_size: 0,
            });
            (group, layout)
        });
        let (source, entry) = if rung == Rung::Bare {
            let k = BareConsts::new(&spec.params, spec.settings.steps_per_period);
            (bare_source(precision, &k), "bare")
        } else {
            (String::new(), "main")
        };
        let mut cache = self.pipelines.lock().unwrap();
        cache
            .entry((precision, rung, variant, source.clone()))
            .or_insert_with(|| {
                let source = if source.is_empty() {
                    shader_source(precision)
                } else {
                    source
                };
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("integrate"),
                    source: wgpu::ShaderSource::Wgsl(source.into()),
                });
                let constants = rung.constants(variant);
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("integrate"),
                    layout: Some(layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        // The bare kernel declares none of the overrides.
                        constants: if rung == Rung::Bare { &[] } else { &constants },
                        ..Default::default()
                    },
                    cache: None,
                })
            })
            .clone()
    }
}
