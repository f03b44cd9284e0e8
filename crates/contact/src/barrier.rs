//! The BFEMP barrier (eq. 27): `b(d) = −κ (d/d̂ − 1)² ln(d/d̂)` for `0 < d < d̂`, 0 beyond.
//!
//! **Convention.** The barrier is a function of the (unsigned) distance `d`, with `κ` in Pa:
//! in 2D `κ · ω_q · b` is a force per unit thickness times a length, i.e. an energy per unit
//! thickness, when `ω_q` is a length (see [`crate::potential`]). Derivatives are given in `d`
//! ([`LogBarrier::first`], [`LogBarrier::second`]) and, since distances are computed squared,
//! chained through `d = √s` by [`LogBarrier::sq_derivatives`]:
//!
//! ```text
//! b'(d)  = −κ [ 2(d/d̂ − 1) ln(d/d̂)/d̂ + (d/d̂ − 1)²/d ]
//! b''(d) = −κ [ 2 ln(d/d̂)/d̂² + 4(d/d̂ − 1)/(d̂ d) − (d/d̂ − 1)²/d² ]
//! ∂b/∂s  = b'(d)/(2d),   ∂²b/∂s² = (b''(d) − b'(d)/d)/(4d²)
//! ```
//!
//! For `κ = 1` this is the IPC Toolkit's `NormalizedClampedLogBarrier` (tests compare the two);
//! the toolkit's plain `barrier(d, d̂) = −(d − d̂)² ln(d/d̂)` is `d̂²` times it.

use crate::ContactError;

/// `b(d) = −κ (d/d̂ − 1)² ln(d/d̂)`: activation distance `dhat` (m) and stiffness `kappa` (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogBarrier {
    /// Activation distance d̂ > 0.
    pub dhat: f64,
    /// Stiffness κ > 0.
    pub kappa: f64,
}

impl LogBarrier {
    /// A validated barrier.
    pub fn new(dhat: f64, kappa: f64) -> Result<Self, ContactError> {
        if !(dhat > 0.0 && dhat.is_finite()) {
            return Err(ContactError::BadParameter {
                what: "dhat",
                value: dhat,
                requirement: "the contact activation distance must be positive and finite",
            });
        }
        if !(kappa > 0.0 && kappa.is_finite()) {
            return Err(ContactError::BadParameter {
                what: "kappa",
                value: kappa,
                requirement: "the barrier stiffness must be positive and finite",
            });
        }
        Ok(Self { dhat, kappa })
    }

    /// `b(d)`; `+∞` for `d ≤ 0`.
    #[inline]
    pub fn value(&self, d: f64) -> f64 {
        if d >= self.dhat {
            return 0.0;
        }
        if d <= 0.0 {
            return f64::INFINITY;
        }
        let r = d / self.dhat;
        -self.kappa * (r - 1.0) * (r - 1.0) * r.ln()
    }

    /// `b'(d)` (≤ 0).
    #[inline]
    pub fn first(&self, d: f64) -> f64 {
        if d >= self.dhat || d <= 0.0 {
            return if d <= 0.0 { f64::NEG_INFINITY } else { 0.0 };
        }
        let r = d / self.dhat;
        -self.kappa * (2.0 * (r - 1.0) * r.ln() / self.dhat + (r - 1.0) * (r - 1.0) / d)
    }

    /// `b''(d)` (≥ 0).
    #[inline]
    pub fn second(&self, d: f64) -> f64 {
        if d >= self.dhat || d <= 0.0 {
            return if d <= 0.0 { f64::INFINITY } else { 0.0 };
        }
        let r = d / self.dhat;
        -self.kappa
            * (2.0 * r.ln() / (self.dhat * self.dhat) + 4.0 * (r - 1.0) / (self.dhat * d)
                - (r - 1.0) * (r - 1.0) / (d * d))
    }

    /// `(b, ∂b/∂s, ∂²b/∂s²)` at squared distance `s = d²`.
    #[inline]
    pub fn sq_derivatives(&self, s: f64) -> (f64, f64, f64) {
        let d = s.sqrt();
        let (b, b1, b2) = (self.value(d), self.first(d), self.second(d));
        if b1 == 0.0 {
            return (b, 0.0, 0.0);
        }
        (b, b1 / (2.0 * d), (b2 - b1 / d) / (4.0 * s))
    }
}
