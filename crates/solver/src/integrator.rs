//! Time integrators in incremental-potential form (BFEMP eqs. 21–22).
//!
//! One step minimises `E(x) = ½‖x − x̂‖²_M + w Φ(x)` with the predictor
//! `x̂ = xⁿ + Δt vⁿ + α(1 − 2β)Δt² aⁿ` and weight `w = 2αβΔt²`; afterwards
//! `aⁿ⁺¹ = (x − x̂)/w` and `vⁿ⁺¹ = vⁿ + Δt((1 − γ)aⁿ + γ aⁿ⁺¹)`. Stationarity gives
//! `M aⁿ⁺¹ = −∇Φ(xⁿ⁺¹)`, the discrete equations of motion.
//!
//! | | α | β | γ | x̂ | w |
//! |---|---|---|---|---|---|
//! | backward Euler | 1 | ½ | 1 | `xⁿ + Δt vⁿ` | `Δt²` |
//! | Newmark (trapezoidal) | ½ | ¼ | ½ | `xⁿ + Δt vⁿ + ¼Δt² aⁿ` | `¼Δt²` |
//!
//! Everything is per DOF, so FEM vertices and MPM grid nodes use it identically.

/// Which scheme.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Integrator {
    /// Backward (implicit) Euler: first order, dissipative.
    #[default]
    BackwardEuler,
    /// Newmark average acceleration (trapezoidal): second order, energy-conserving for linear
    /// problems.
    Newmark,
}

impl Integrator {
    /// `(α, β, γ)`.
    pub fn coefficients(self) -> (f64, f64, f64) {
        match self {
            Integrator::BackwardEuler => (1.0, 0.5, 1.0),
            Integrator::Newmark => (0.5, 0.25, 0.5),
        }
    }

    /// Whether the scheme needs the previous acceleration (only Newmark).
    pub fn needs_acceleration(self) -> bool {
        matches!(self, Integrator::Newmark)
    }

    /// The energy weight `w = 2αβΔt²` multiplying the potential.
    pub fn weight(self, dt: f64) -> f64 {
        let (a, b, _) = self.coefficients();
        2.0 * a * b * dt * dt
    }

    /// Predictor `x̂ = x + Δt v + α(1 − 2β)Δt² a` into `out`.
    pub fn predictor(self, dt: f64, x: &[f64], v: &[f64], a: &[f64], out: &mut [f64]) {
        let (al, be, _) = self.coefficients();
        let c = al * (1.0 - 2.0 * be) * dt * dt;
        for i in 0..out.len() {
            out[i] = x[i] + dt * v[i] + if c != 0.0 { c * a[i] } else { 0.0 };
        }
    }

    /// After the solve: new acceleration `a ← (x − x̂)/w` and velocity
    /// `v ← v + Δt((1 − γ)a_old + γ a_new)`, in place.
    pub fn update(self, dt: f64, x_new: &[f64], x_hat: &[f64], v: &mut [f64], a: &mut [f64]) {
        let (_, _, ga) = self.coefficients();
        let w = self.weight(dt);
        for i in 0..v.len() {
            let a_new = (x_new[i] - x_hat[i]) / w;
            v[i] += dt * ((1.0 - ga) * a[i] + ga * a_new);
            a[i] = a_new;
        }
    }
}
