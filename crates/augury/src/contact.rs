//! The augury contact correction (eqs. 29 and 36–46).

use std::time::Instant;

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::error::{AuguryError, check_len};
use crate::operator::{Transfer, TransferKind};

/// Particles per parallel task in the per-particle loops (below it, one thread does them all).
const MIN_LEN: usize = 4096;

/// What the iterations treat as undesirable in the proposed velocity change `ΔV`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ContactModel {
    /// No iterations: `Â = G V̄ / τ` — bodies stick on contact (§2.2).
    Sticky,
    /// Eq. 38: a change that pulls a particle away from its surface (`Δv·n > 0`) is undone, so
    /// bodies can separate; tangential sticking remains.
    Separation,
    /// Eqs. 42–46 with Coulomb coefficient μ ≥ 0: separation as above, and the tangential change
    /// beyond `μ |Δv·n|` is undone (μ = 0: frictionless sliding). `ΔB` is always undone.
    Friction(f64),
}

/// Parameters of the correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AuguryParams {
    /// Look-ahead time τ (s); the paper uses the time step.
    pub tau: f64,
    /// Number of augury iterations N (the paper uses 1); ignored for [`ContactModel::Sticky`].
    pub iterations: usize,
    /// The contact model.
    pub model: ContactModel,
}

impl AuguryParams {
    fn check(&self) -> Result<(), AuguryError> {
        if !(self.tau > 0.0 && self.tau.is_finite()) {
            return Err(AuguryError::BadParameter {
                name: "tau",
                value: self.tau,
                requirement: "must be positive and finite",
            });
        }
        if let ContactModel::Friction(mu) = self.model
            && !(mu >= 0.0 && mu.is_finite())
        {
            return Err(AuguryError::BadParameter {
                name: "friction coefficient",
                value: mu,
                requirement: "must be non-negative and finite",
            });
        }
        Ok(())
    }
}

/// Wall time of the parts of the last [`AuguryContact::correction`] (s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CorrectionTiming {
    /// Placing the particles on the grid: their stencils and the active-node numbering
    /// ([`Transfer::set_positions`]).
    pub stencils_s: f64,
    /// The transfers `H` (particle-to-grid, normalisation, grid-to-particle): one for `G V̄`
    /// and one per augury iteration that changed anything.
    pub transfers_s: f64,
    /// Transfers applied.
    pub transfers: usize,
    /// The whole correction (the above and the per-particle updates).
    pub total_s: f64,
}

/// Computes `Â = (V̂ − V̄)/τ` for the boundary particles, reusing its buffers between calls.
pub struct AuguryContact<const D: usize> {
    transfer: Transfer<D>,
    params: AuguryParams,
    timing: CorrectionTiming,
    hv: Vec<SVector<f64, D>>,
    hb: Vec<SMatrix<f64, D, D>>,
    wv: Vec<SVector<f64, D>>,
    wb: Vec<SMatrix<f64, D, D>>,
    dv: Vec<SVector<f64, D>>,
    db: Vec<SMatrix<f64, D, D>>,
}

impl<const D: usize> AuguryContact<D> {
    /// A correction with the given transfer and parameters.
    pub fn new(transfer: Transfer<D>, params: AuguryParams) -> Result<Self, AuguryError> {
        params.check()?;
        Ok(Self {
            transfer,
            params,
            timing: CorrectionTiming::default(),
            hv: Vec::new(),
            hb: Vec::new(),
            wv: Vec::new(),
            wb: Vec::new(),
            dv: Vec::new(),
            db: Vec::new(),
        })
    }

    /// The transfer `H`.
    pub fn transfer(&self) -> &Transfer<D> {
        &self.transfer
    }

    /// The parameters.
    pub fn params(&self) -> &AuguryParams {
        &self.params
    }

    /// Where the last correction's time went.
    pub fn timing(&self) -> CorrectionTiming {
        self.timing
    }

    /// The correction for particles at `x` with masses `mass`, unit outward normals `normal`
    /// (zero: no constraint on that particle) and predicted field `V̄ = (v̄, B̄)` (eq. 27):
    /// writes `â` into `a_out` and `Ḃ̂` into `bdot_out`. Returns the number of augury
    /// iterations that changed anything.
    #[allow(clippy::too_many_arguments)]
    pub fn correction(
        &mut self,
        x: &[SVector<f64, D>],
        mass: &[f64],
        normal: &[SVector<f64, D>],
        vbar: &[SVector<f64, D>],
        bbar: &[SMatrix<f64, D, D>],
        a_out: &mut [SVector<f64, D>],
        bdot_out: &mut [SMatrix<f64, D, D>],
    ) -> Result<usize, AuguryError> {
        let start = Instant::now();
        let n = x.len();
        check_len("normals", n, normal.len())?;
        check_len("predicted B", n, bbar.len())?;
        check_len("acceleration output", n, a_out.len())?;
        check_len("B-rate output", n, bdot_out.len())?;
        let apic = self.transfer.kind() == TransferKind::Apic;
        for buf in [&mut self.hv, &mut self.wv, &mut self.dv] {
            buf.resize(n, SVector::zeros());
        }
        for buf in [&mut self.hb, &mut self.wb, &mut self.db] {
            buf.resize(n, SMatrix::zeros());
        }
        let clock = Instant::now();
        self.transfer.set_positions(x)?;
        self.timing.stencils_s = clock.elapsed().as_secs_f64();
        // ΔV₀ = G V̄ = H V̄ − V̄.
        let clock = Instant::now();
        self.transfer
            .apply(mass, vbar, bbar, &mut self.hv, &mut self.hb)?;
        self.timing.transfers_s = clock.elapsed().as_secs_f64();
        self.timing.transfers = 1;
        let iterations = match self.params.model {
            ContactModel::Sticky => 0,
            _ => self.params.iterations,
        };
        let model = self.params.model;
        let inv_tau = 1.0 / self.params.tau;
        // W = the undesirable part of the change proposed so far (eq. 38 / 44–46), written to
        // `(wv, wb)`; whether it is not zero.
        let undesirable = |dv: &SVector<f64, D>,
                           db: &SMatrix<f64, D, D>,
                           n: &SVector<f64, D>,
                           wv: &mut SVector<f64, D>,
                           wb: &mut SMatrix<f64, D, D>| {
            let (w, b) = undesirable_part(model, dv, db, n);
            *wv = w;
            *wb = if apic { b } else { SMatrix::zeros() };
            w != SVector::<f64, D>::zeros() || b != SMatrix::<f64, D, D>::zeros()
        };
        // The per-particle passes are fused (ΔV₀ with the first W; each update with the next W,
        // or with the output after the last iteration): every pass streams the D×D matrices of
        // all particles, and memory bandwidth is what they cost.
        let mut any = (
            &mut self.dv,
            &mut self.db,
            &mut self.wv,
            &mut self.wb,
            &self.hv,
            &self.hb,
            vbar,
            bbar,
            normal,
        )
            .into_par_iter()
            .with_min_len(MIN_LEN)
            .map(|(dv, db, wv, wb, hv, hb, v, b, n)| {
                *dv = hv - v;
                *db = if apic { hb - b } else { SMatrix::zeros() };
                iterations > 0 && undesirable(dv, db, n, wv, wb)
            })
            .reduce(|| false, |a, b| a | b);
        let mut active = 0;
        let mut written = false;
        for it in 0..iterations {
            if !any {
                break;
            }
            active += 1;
            // ΔV += G W.
            let clock = Instant::now();
            self.transfer
                .apply(mass, &self.wv, &self.wb, &mut self.hv, &mut self.hb)?;
            self.timing.transfers_s += clock.elapsed().as_secs_f64();
            self.timing.transfers += 1;
            let last = it + 1 == iterations;
            any = (
                &mut self.dv,
                &mut self.db,
                &mut self.wv,
                &mut self.wb,
                &self.hv,
                &self.hb,
                normal,
                &mut *a_out,
                &mut *bdot_out,
            )
                .into_par_iter()
                .with_min_len(MIN_LEN)
                .map(|(dv, db, wv, wb, hv, hb, n, a, bdot)| {
                    *dv += hv - *wv;
                    if apic {
                        *db += hb - *wb;
                    }
                    if last {
                        *a = *dv * inv_tau;
                        *bdot = *db * inv_tau;
                        false
                    } else {
                        undesirable(dv, db, n, wv, wb)
                    }
                })
                .reduce(|| false, |a, b| a | b);
            written = last;
        }
        if !written {
            (a_out, bdot_out, &self.dv, &self.db)
                .into_par_iter()
                .with_min_len(MIN_LEN)
                .for_each(|(a, bdot, dv, db)| {
                    *a = dv * inv_tau;
                    *bdot = db * inv_tau;
                });
        }
        self.timing.total_s = start.elapsed().as_secs_f64();
        Ok(active)
    }
}

/// The undesirable part `(Δv^u, ΔB^u)` of a proposed change `(Δv, ΔB)` of a particle with unit
/// outward normal `n` (zero: unconstrained, nothing undesirable) under `model`: eq. 38
/// (separation: all of it when `Δv·n > 0`) or eqs. 42–45 (friction: also the tangential part
/// beyond `μ |Δv·n|`, and all of `ΔB`). The iterations apply `G` to it; a change whose
/// undesirable part is zero satisfies the contact model at that particle.
pub fn undesirable_part<const D: usize>(
    model: ContactModel,
    dv: &SVector<f64, D>,
    db: &SMatrix<f64, D, D>,
    n: &SVector<f64, D>,
) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
    if *n == SVector::<f64, D>::zeros() {
        return (SVector::zeros(), SMatrix::zeros());
    }
    let dn = dv.dot(n);
    match model {
        ContactModel::Sticky => (SVector::zeros(), SMatrix::zeros()),
        ContactModel::Separation => {
            if dn > 0.0 {
                (*dv, *db)
            } else {
                (SVector::zeros(), SMatrix::zeros())
            }
        }
        ContactModel::Friction(mu) => {
            if dn > 0.0 {
                return (*dv, *db);
            }
            let t = dv - n * dn;
            let tl = t.norm();
            let s = tl.min(-mu * dn);
            let w = if tl > 0.0 { t * (1.0 - s / tl) } else { t };
            (w, *db)
        }
    }
}
