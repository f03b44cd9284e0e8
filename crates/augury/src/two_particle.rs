//! The 1D two-particle analysis of §3.1 (eqs. 47–50), non-dimensionalised by the half cell
//! length L and the initial speed v0: two equal particles start at ∓1 moving towards each other
//! at unit speed inside one linear-element cell `[−1, 1]`; by symmetry only the left particle
//! `(x, v, B)` is tracked. With τ the non-dimensional look-ahead `τ v0 / L`:
//!
//! * APIC (eq. 49): `ẋ = v`, `v̇ = ((x² − 1) v − x B)/τ`, `Ḃ = ((x³ − x) v − x² B)/τ`;
//! * PIC (eq. 50): `ẋ = v`, `v̇ = (x² − 1) v / τ`.
//!
//! The only rest state of APIC with `B ≠ 0` is `x = v = 0` (zero gap); PIC rests wherever
//! `v = 0` (a finite gap). Large τ lets the particles pass each other.

/// State of the left particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    /// Position (−1 at the start).
    pub x: f64,
    /// Velocity (1 at the start).
    pub v: f64,
    /// Scaled velocity gradient (APIC).
    pub b: f64,
}

fn rhs(s: &State, tau: f64, apic: bool) -> State {
    let (x, v, b) = (s.x, s.v, s.b);
    if apic {
        State {
            x: v,
            v: ((x * x - 1.0) * v - x * b) / tau,
            b: ((x * x * x - x) * v - x * x * b) / tau,
        }
    } else {
        State {
            x: v,
            v: (x * x - 1.0) * v / tau,
            b: 0.0,
        }
    }
}

fn axpy(s: &State, k: &State, h: f64) -> State {
    State {
        x: s.x + h * k.x,
        v: s.v + h * k.v,
        b: s.b + h * k.b,
    }
}

/// Integrate from `(−1, 1, 0)` with classical RK4 at step `dt` until `t_end`, or until the
/// particle leaves the cell `|x| > 1` after having entered it (the particles passed each other
/// or bounced out). Returns the trajectory `(t, state)`.
pub fn integrate(tau: f64, apic: bool, dt: f64, t_end: f64) -> Vec<(f64, State)> {
    let mut s = State {
        x: -1.0,
        v: 1.0,
        b: 0.0,
    };
    let mut t = 0.0;
    let mut out = vec![(t, s)];
    while t < t_end {
        let k1 = rhs(&s, tau, apic);
        let k2 = rhs(&axpy(&s, &k1, 0.5 * dt), tau, apic);
        let k3 = rhs(&axpy(&s, &k2, 0.5 * dt), tau, apic);
        let k4 = rhs(&axpy(&s, &k3, dt), tau, apic);
        s = State {
            x: s.x + dt / 6.0 * (k1.x + 2.0 * k2.x + 2.0 * k3.x + k4.x),
            v: s.v + dt / 6.0 * (k1.v + 2.0 * k2.v + 2.0 * k3.v + k4.v),
            b: s.b + dt / 6.0 * (k1.b + 2.0 * k2.b + 2.0 * k3.b + k4.b),
        };
        t += dt;
        out.push((t, s));
        if s.x > 1.0 {
            break;
        }
    }
    out
}

/// Outcome of [`simulate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Meeting {
    /// Final gap `x_right − x_left` in cells (negative: they passed each other).
    pub gap_cells: f64,
    /// Final speed of the left particle, in units of v0.
    pub speed: f64,
    /// Steps taken.
    pub steps: usize,
}

/// The same experiment with the real operator: two unit-mass particles on a 2D grid of spacing
/// 1, four cells apart on a line off the grid lines (y = 0.37), approaching at unit speed,
/// interacting only through the augury correction `Â = G V / τ` (no iteration, no other force),
/// integrated with `Δt = min(τ, 0.01)`. Stops at rest (`|v| < 1e-9`), when they have separated
/// by more than 3 cells after passing, or after `max_steps`.
pub fn simulate(
    kernel: femp_kernels::Kernel,
    kind: crate::TransferKind,
    tau: f64,
    max_steps: usize,
) -> Result<Meeting, crate::AuguryError> {
    use nalgebra::{Matrix2, Vector2};
    let transfer = crate::Transfer::<2>::new(1.0, kernel, kind)?;
    let mut aug = crate::AuguryContact::new(
        transfer,
        crate::AuguryParams {
            tau,
            iterations: 0,
            model: crate::ContactModel::Sticky,
        },
    )?;
    let dt = tau.min(0.01);
    let y = 0.37;
    let mut x = [Vector2::new(-2.0, y), Vector2::new(2.0, y)];
    let mut v = [Vector2::new(1.0, 0.0), Vector2::new(-1.0, 0.0)];
    let mut b = [Matrix2::zeros(); 2];
    let (m, n) = ([1.0, 1.0], [Vector2::zeros(); 2]);
    let (mut a, mut bd) = ([Vector2::zeros(); 2], [Matrix2::zeros(); 2]);
    let mut steps = 0;
    while steps < max_steps {
        aug.correction(&x, &m, &n, &v, &b, &mut a, &mut bd)?;
        for p in 0..2 {
            v[p] += a[p] * dt;
            b[p] += bd[p] * dt;
            x[p] += v[p] * dt;
        }
        steps += 1;
        if v[0].norm() < 1e-9 || x[0][0] > x[1][0] + 3.0 {
            break;
        }
    }
    Ok(Meeting {
        gap_cells: x[1][0] - x[0][0],
        speed: v[0].norm(),
        steps,
    })
}
