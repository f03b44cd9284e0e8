//! Validation of particle arrays before a transfer: every bad value is reported with the
//! index of the first particle that has one.

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::KernelError;
use crate::error::check_len;

/// Check masses (finite, ≥ 0).
pub(crate) fn masses(mass: &[f64], n: usize) -> Result<(), KernelError> {
    check_len("particle masses", n, mass.len())?;
    let bad = |m: &f64| !(m.is_finite() && *m >= 0.0);
    if mass.par_iter().with_min_len(8192).any(bad) {
        let p = mass.iter().position(bad).unwrap_or(0);
        let m = mass[p];
        return Err(if m.is_finite() {
            KernelError::NegativeMass {
                particle: p,
                mass: m,
            }
        } else {
            KernelError::NonFinite {
                particle: p,
                quantity: "mass",
                value: m,
            }
        });
    }
    Ok(())
}

/// Check a per-particle vector quantity (finite).
pub(crate) fn vectors<const D: usize>(
    what: &'static str,
    v: &[SVector<f64, D>],
    n: usize,
) -> Result<(), KernelError> {
    check_len(what, n, v.len())?;
    finite(what, v, |x| x.as_slice())
}

/// Check a per-particle matrix quantity (finite).
pub(crate) fn matrices<const D: usize>(
    what: &'static str,
    m: &[SMatrix<f64, D, D>],
    n: usize,
) -> Result<(), KernelError> {
    check_len(what, n, m.len())?;
    finite(what, m, |x| x.as_slice())
}

fn finite<T: Sync>(
    what: &'static str,
    items: &[T],
    comps: impl Fn(&T) -> &[f64] + Sync,
) -> Result<(), KernelError> {
    let bad = |x: &T| comps(x).iter().any(|c| !c.is_finite());
    if items.par_iter().with_min_len(8192).any(bad) {
        let p = items.iter().position(bad).unwrap_or(0);
        let value = comps(&items[p])
            .iter()
            .copied()
            .find(|c| !c.is_finite())
            .unwrap_or(f64::NAN);
        return Err(KernelError::NonFinite {
            particle: p,
            quantity: what,
            value,
        });
    }
    Ok(())
}
