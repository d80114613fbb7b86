//! A point's run on the integrator: its start, the transient and sampled periods, the
//! exponent and the result (the twin of the kernel's loop in `shaders/main.wgsl`).

use super::*;

impl<F: Real> Integrator<F> {
    /// Start state (mode from the at-rest rule when v = 0).
    pub fn start(&self, y0: [f64; 4]) -> PointState<F> {
        self.start_in(y0, None)
    }

    /// Start state in `mode` where given (a continued run), else as [`Integrator::start`].
    pub fn start_in(&self, y0: [f64; 4], mode: Option<Mode>) -> PointState<F> {
        let y = y0.map(F::of);
        PointState {
            y,
            mode: mode.unwrap_or_else(|| initial_mode(&self.p, &y, F::one())),
            diag: Diagnostics {
                // Non-finite input fails the point before it runs.
                nonfinite: !self.p.is_finite() || !y.iter().all(|v| v.is_finite()),
                ..Diagnostics::default()
            },
        }
    }

    /// Integrates `transient` periods, then records `samples` stroboscopic states.
    pub fn run(&self, y0: [f64; 4], transient: u32, samples: u32) -> RunResult {
        let mut st = self.start(y0);
        self.run_from(&mut st, transient, samples)
    }

    /// As [`Integrator::run`], from a given state (continuation).
    pub fn run_from(&self, st: &mut PointState<F>, transient: u32, samples: u32) -> RunResult {
        for _ in 0..transient {
            if st.diag.nonfinite {
                break;
            }
            crate::progress::poll();
            self.period(st);
        }
        self.sample(st, samples)
    }

    /// The sampled part of [`Integrator::run_from`]: `samples` periods, each ending in a
    /// stroboscopic sample, with the exponent when the settings ask for it.
    pub fn sample(&self, st: &mut PointState<F>, samples: u32) -> RunResult {
        let before = st.diag.impacts;
        // The observables are those of the sampled periods.
        st.diag.start_sampling();
        let mut out = Vec::with_capacity(samples as usize);
        // The Lyapunov estimate: a tangent vector along y1 at the start of sampling, carried
        // through the same stages and events as the state (which it leaves bit for bit as
        // without it), renormalised at each section.
        let mut tangent = tangent::Leading::<F>::default();
        let mut tangent_ok = self.lyapunov;
        let mut growth = Growth::new(samples);
        for _ in 0..samples {
            if st.diag.nonfinite {
                break;
            }
            crate::progress::poll();
            if tangent_ok {
                self.period_observed(st, &mut tangent);
            } else {
                self.period(st);
            }
            if st.diag.nonfinite {
                break;
            }
            out.push(st.y.map(|v| v.to_f64()));
            if tangent_ok {
                tangent_ok = tangent.is_finite();
                if tangent_ok {
                    growth.push(tangent.renormalize());
                }
            }
        }
        let exponent = self.exponent(tangent_ok, &growth, samples);
        self.result(st, out, before, exponent)
    }

    /// The largest exponent and its standard error per unit time from the log growth over the
    /// sampled periods; NaN without a running tangent or samples.
    pub(crate) fn exponent(&self, tangent_ok: bool, growth: &Growth, samples: u32) -> Exponent {
        let period = 2.0 * std::f64::consts::PI / self.p.eta.to_f64();
        if tangent_ok && samples > 0 {
            growth.exponent(period)
        } else {
            Exponent::NONE
        }
    }

    /// The result of a run whose sampling started with `before` impacts.
    pub(super) fn result(
        &self,
        st: &PointState<F>,
        samples: Vec<[f64; 4]>,
        before: u64,
        lyapunov: Exponent,
    ) -> RunResult {
        let mut torus = Birkhoff::new(samples.len() as u32);
        let (dissipation, stick_fraction) = energy(&st.diag, samples.len(), self.n);
        samples.iter().for_each(|s| torus.push(s[0]));
        RunResult {
            exponent_lost: self.lyapunov
                && lyapunov.value.is_nan()
                && !st.diag.nonfinite
                && !samples.is_empty(),
            torus: torus.digits(),
            tail: tail_of(&samples),
            samples,
            sample_impacts: st.diag.impacts - before,
            diag: st.diag,
            final_y: st.y.map(|v| v.to_f64()),
            final_mode: st.mode,
            lyapunov,
            detector: None,
            impact_speed: impact_speed(&st.diag, st.diag.impacts - before),
            dissipation,
            stick_fraction,
        }
    }
}
