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

/// The entry points of Newton's method (file name, text): its flows (`flows`) and its
/// iteration (`newton`). They compile after the pieces of [`SHADER`] but `main.wgsl`, with four
/// tangent vectors ([`flows_source`]).
pub const FLOWS_SHADER: [(&str, &str); 2] = [
    ("flows.wgsl", include_str!("../../shaders/flows.wgsl")),
    ("newton.wgsl", include_str!("../../shaders/newton.wgsl")),
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
    source(precision, 1, &SHADER)
}

/// The source of Newton's method in a precision: the kernel's pieces with four tangent vectors
/// and the entry points of [`FLOWS_SHADER`] instead of `main.wgsl`.
pub fn flows_source(precision: Precision) -> String {
    let mut pieces = SHADER.to_vec();
    pieces.pop();
    pieces.extend(FLOWS_SHADER);
    source(precision, 4, &pieces)
}

/// The prelude, the number of tangent vectors (`TANGENTS`), then the pieces.
fn source(precision: Precision, tangents: u32, pieces: &[(&str, &str)]) -> String {
    let mut src = layout::prelude(precision);
    src += &format!("\n// Tangent vectors (tangent.wgsl).\nconst TANGENTS: u32 = {tangents}u;\n");
    for (name, text) in pieces {
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

/// A compiled pipeline's precision, rung, variant, source (empty: the production kernel's) and
/// entry point.
type PipelineKey = (Precision, Rung, Variant, String, String);

/// Compiled kernels per precision, rung and variant, built on first use
/// (continuation runs many small jobs and compiles once; a run that never asks for f64 never
/// compiles it).
#[derive(Default)]
pub(super) struct Kernels {
    pipelines: Mutex<HashMap<PipelineKey, wgpu::ComputePipeline>>,
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
        if rung == Rung::Bare {
            let k = BareConsts::new(&spec.params, spec.settings.steps_per_period);
            // The bare kernel declares none of the overrides.
            return self.compile(
                device,
                (precision, rung, variant),
                bare_source(precision, &k),
                "bare",
                &[],
            );
        }
        self.compile(
            device,
            (precision, rung, variant),
            String::new(),
            "main",
            &rung.constants(variant),
        )
    }

    /// The pipeline of Newton's entry point `entry` (`flows` or `newton`, [`flows_source`]; the
    /// production kernel's pieces, with the tangent).
    pub(super) fn flows(
        &self,
        device: &wgpu::Device,
        precision: Precision,
        coulomb: bool,
        entry: &str,
    ) -> wgpu::ComputePipeline {
        let variant = Variant {
            coulomb,
            tangent: true,
            uniform_table: false,
        };
        self.compile(
            device,
            (precision, Rung::Full, variant),
            flows_source(precision),
            entry,
            &Rung::Full.constants(variant),
        )
    }

    /// The cached pipeline of `key` and `source` (empty: the production kernel's), compiled on
    /// first use with entry point `entry` and the override `constants`.
    fn compile(
        &self,
        device: &wgpu::Device,
        (precision, rung, variant): (Precision, Rung, Variant),
        source: String,
        entry: &str,
        constants: &[(&str, f64)],
    ) -> wgpu::ComputePipeline {
        let (_, layout) = self.layout.get_or_init(|| {
            let group = bind_group_layout(device);
            let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("integrate"),
                bind_group_layouts: &[Some(&group)],
                immediate_size: 0,
            });
            (group, layout)
        });
        let mut cache = self.pipelines.lock().unwrap();
        cache
            .entry((precision, rung, variant, source.clone(), entry.to_string()))
            .or_insert_with(|| {
                let t0 = std::time::Instant::now();
                let source = if source.is_empty() {
                    shader_source(precision)
                } else {
                    source
                };
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(entry),
                    source: wgpu::ShaderSource::Wgsl(source.into()),
                });
                let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants,
                        ..Default::default()
                    },
                    cache: None,
                });
                // Start-up is part of every short run's wall (docs/performance.md).
                log::debug!(
                    "pipeline {entry} ({precision:?}, {rung:?}, {variant:?}) built in {:.3} s",
                    t0.elapsed().as_secs_f64()
                );
                pipeline
            })
            .clone()
    }
}
