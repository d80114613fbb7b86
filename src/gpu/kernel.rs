//! The kernel: its source and its compiled pipelines.

use super::layout;
use crate::config::Precision;
use std::sync::Mutex;

/// The kernel body as written. It does not compile alone: the precision alias, the constants
/// and `Control` come from the prelude (see [`shader_source`]).
pub const SHADER: &str = include_str!("../../shaders/integrate.wgsl");

/// The kernel source in a precision: the generated contract of `layout`, then the body.
/// The one way to get the kernel text, for the runner and the tests alike.
pub fn shader_source(precision: Precision) -> String {
    layout::prelude(precision) + SHADER
}

/// Compiled kernels per precision, built on first use (continuation runs many small jobs and
/// compiles once; a run that never asks for f64 never compiles it).
#[derive(Default)]
pub(super) struct Kernels {
    pipelines: Mutex<[Option<wgpu::ComputePipeline>; 2]>,
}

impl Kernels {
    pub(super) fn get(&self, device: &wgpu::Device, precision: Precision) -> wgpu::ComputePipeline {
        let slot = match precision {
            Precision::F32 => 0,
            Precision::F64 => 1,
        };
        let mut cache = self.pipelines.lock().unwrap();
        cache[slot]
            .get_or_insert_with(|| {
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("integrate"),
                    source: wgpu::ShaderSource::Wgsl(shader_source(precision).into()),
                });
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("integrate"),
                    layout: None,
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
            .clone()
    }
}
