//! rattle: parameter sweeps of an impact oscillator with dry friction, on GPU and CPU.
//!
//! One module per concept: [`model`] (equations), [`method`] (the CPU integrator and its tangent
//! dynamics, twin of the kernel's pieces in `shaders/`), [`cpu`] and [`gpu`] (the backends) under
//! [`engine`], [`class`], [`classify`], [`decide`], [`cycles`] and [`stability`] (what a run is),
//! [`adaptive`] (the one driver every command asks: horizon, long look) and [`carry`],
//! [`bifurcation`], [`map`], [`basin`] and [`point`] (the commands), [`explore`] (a map as a
//! live page: its library half), [`config`], [`render`],
//! [`output`].

pub mod accuracy;
pub mod adaptive;
pub mod basin;
pub mod bench;
pub mod bifurcation;
pub mod caption;
pub mod carry;
pub mod class;
pub mod classify;
pub mod config;
pub mod cpu;
pub mod cycles;
pub mod decide;
pub mod engine;
pub mod error;
pub mod escape;
pub mod explore;
pub mod gpu;

pub mod map;
pub mod memory;
pub mod method;
pub mod model;
pub mod observables;
pub mod output;
pub mod point;
pub mod progress;
pub mod real;
pub mod recurrence;
pub mod reference;
pub mod render;
pub mod request;
pub mod sensitivity;
pub mod spec;
pub mod stability;
pub mod stats;
pub mod validate;

pub use error::{Error, Result};
