//! Lagged, smoothed Coulomb friction (BFEMP §4.3, eqs. 34–37; after Li et al. 2020).
//!
//! # What is lagged, and where Δt enters
//!
//! For each active contact term `k` (a particle and its closest boundary feature, as merged by
//! [`crate::ContactPotential::collect_terms`]) the lagged state `xʲ` fixes:
//!
//! * the **normal force magnitude** `λ_k = −w_k b'(d_k) ≥ 0` (N in 3D, N/m in 2D), where
//!   `w_k = ω_q × coefficient` — the same force the barrier exerts, so friction and normal
//!   force use one set of duplicate-removal coefficients;
//! * the **closest point's barycentric weights** `β_i` on the feature (vertex: `1`; edge:
//!   `1−t, t`; face: `1−β₁−β₂, β₁, β₂`);
//! * an orthonormal **tangent basis** `T_k` (`D × (D−1)`) of the plane orthogonal to the contact
//!   normal (`p − c`, or the face normal).
//!
//! With displacements over the step `Δx = x − xⁿ` (for a particle: its grid-interpolated
//! displacement `Σ_i w_ip Δx_i`, never its own velocity — §4.3), the relative tangential
//! **displacement** is `u_k = T_kᵀ (Δx_q − Σ_i β_i Δx_i)` — a length, not a velocity. The
//! friction pseudo-potential (eq. 37) is
//!
//! ```text
//! D(x) = Σ_k μ λ_k f₀(|u_k|),   f₀(y) = −y³/(3ε²) + y²/ε + ε/3  (y < ε),  y  (y ≥ ε),
//! ε = ε_v Δt
//! ```
//!
//! so `f₁ = f₀' = −y²/ε² + 2y/ε` for `y < ε` (eq. 36) and `1` beyond. `ε_v` is in m/s, so
//! `ε = ε_v Δt` is the displacement below which sliding counts as sticking: this is the single
//! place Δt appears. `μ λ f₀` is then a force times a length — an energy, as the incremental
//! potential needs — and `−∇D` is `−μ λ T f₁(|u|) u/|u|`, the mollified Coulomb force of
//! eq. 35. (A common confusion is to mollify `|u|/Δt` with `ε_v` and forget that the potential
//! then needs a factor Δt: same thing, written here once.)
//!
//! # Derivatives
//! On the stencil `(particle, feature vertices)` with `c = (1, −β_1, …)`:
//! `∂D_k/∂x_a = c_a μλ (f₁(y)/y) T u`, and the Hessian block `(a, b)` is
//! `c_a c_b μλ T M Tᵀ` with `M = f₁'(y) ûûᵀ + (f₁(y)/y)(I − ûûᵀ)` (`M = f₁'(|u|)` in 2D).
//! `f₁' ≥ 0` and `f₁/y > 0` make `M` — and the Hessian, for `λ ≥ 0` — positive semi-definite
//! with no projection; terms with `λ ≤ 0` (possible only where duplicate removal leaves a net
//! negative coefficient) are dropped. At `y → 0` the limits `f₁/y → 2/ε`, `f₁' → 2/ε` are used.

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::ContactError;
use crate::distance::point_edge;
use crate::distance::point_triangle;
use crate::potential::{ContactPotential, ContactTerm, Feature, TermDerivatives};

/// `f₀(y)` with threshold `eps` (a displacement: `ε_v Δt`).
#[inline]
pub fn f0(y: f64, eps: f64) -> f64 {
    let y = y.abs();
    if y >= eps {
        y
    } else {
        -y * y * y / (3.0 * eps * eps) + y * y / eps + eps / 3.0
    }
}

/// `f₁(y) = f₀'(y)`.
#[inline]
pub fn f1(y: f64, eps: f64) -> f64 {
    let y = y.abs();
    if y >= eps {
        1.0
    } else {
        -y * y / (eps * eps) + 2.0 * y / eps
    }
}

/// `f₁(y)/y` (limit `2/ε` at 0).
#[inline]
pub fn f1_over_y(y: f64, eps: f64) -> f64 {
    let y = y.abs();
    if y >= eps {
        1.0 / y
    } else {
        -y / (eps * eps) + 2.0 / eps
    }
}

/// `f₁'(y)`.
#[inline]
pub fn f1_prime(y: f64, eps: f64) -> f64 {
    let y = y.abs();
    if y >= eps {
        0.0
    } else {
        -2.0 * y / (eps * eps) + 2.0 / eps
    }
}

/// Friction parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionParams {
    /// Coulomb coefficient μ ≥ 0.
    pub mu: f64,
    /// Static-friction velocity threshold ε_v > 0 (m/s).
    pub eps_v: f64,
    /// Time step Δt > 0 (s).
    pub dt: f64,
}

impl FrictionParams {
    /// Validated parameters.
    pub fn new(mu: f64, eps_v: f64, dt: f64) -> Result<Self, ContactError> {
        let bad = |what, value, requirement| {
            Err(ContactError::BadParameter {
                what,
                value,
                requirement,
            })
        };
        if !(mu >= 0.0 && mu.is_finite()) {
            return bad(
                "mu",
                mu,
                "the friction coefficient must be non-negative and finite",
            );
        }
        if !(eps_v > 0.0 && eps_v.is_finite()) {
            return bad(
                "eps_v",
                eps_v,
                "the static friction velocity threshold must be positive",
            );
        }
        if !(dt > 0.0 && dt.is_finite()) {
            return bad("dt", dt, "the time step must be positive");
        }
        Ok(Self { mu, eps_v, dt })
    }

    /// The mollifier threshold as a displacement, `ε = ε_v Δt`.
    #[inline]
    pub fn eps(&self) -> f64 {
        self.eps_v * self.dt
    }
}

/// One lagged friction term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionTerm<const D: usize> {
    /// Particle index.
    pub particle: u32,
    /// Feature vertices (first `n − 1` valid).
    pub vertices: [u32; 3],
    /// Stencil size.
    pub n: usize,
    /// Barycentric weights of the closest point on the feature.
    pub beta: [f64; 3],
    /// Tangent basis (first `D − 1` vectors valid).
    pub basis: [SVector<f64, D>; 2],
    /// Lagged normal force magnitude λ.
    pub lambda: f64,
}

/// An orthonormal basis of the plane (line in 2D) orthogonal to unit `n`.
pub fn orthogonal_basis<const D: usize>(n: &SVector<f64, D>) -> [SVector<f64, D>; 2] {
    let mut b = [SVector::<f64, D>::zeros(); 2];
    if D == 2 {
        b[0][0] = -n[1];
        b[0][1] = n[0];
    } else {
        // Cross with the coordinate axis least aligned with n.
        let k = (0..D)
            .min_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))
            .unwrap_or(0);
        let mut axis = SVector::<f64, D>::zeros();
        axis[k] = 1.0;
        let n3 = nalgebra::Vector3::new(n[0], n[1], n[D - 1]);
        let a3 = nalgebra::Vector3::new(axis[0], axis[1], axis[D - 1]);
        let t1 = n3.cross(&a3).normalize();
        let t2 = n3.cross(&t1);
        b[0] = SVector::from_fn(|i, _| t1[i]);
        b[1] = SVector::from_fn(|i, _| t2[i]);
    }
    b
}

/// Closest point weights and tangent basis of a particle against a feature.
pub fn closest_point_frame<const D: usize>(
    p: &SVector<f64, D>,
    feature: Feature,
    boundary: &[SVector<f64, D>],
) -> ([f64; 3], [SVector<f64, D>; 2]) {
    match feature {
        Feature::Vertex(a) => {
            let n = (p - boundary[a as usize]).normalize();
            ([1.0, 0.0, 0.0], orthogonal_basis(&n))
        }
        Feature::Edge(a, b) => {
            let (xa, xb) = (&boundary[a as usize], &boundary[b as usize]);
            let t = point_edge::parameter(p, xa, xb).clamp(0.0, 1.0);
            let c = xa + (xb - xa) * t;
            let n = (p - c).normalize();
            let mut basis = orthogonal_basis(&n);
            if D == 3 {
                // Edge direction first (matches the IPC Toolkit's point–edge basis up to sign).
                let e = (xb - xa).normalize();
                let n3 = nalgebra::Vector3::new(n[0], n[1], n[D - 1]);
                let e3 = nalgebra::Vector3::new(e[0], e[1], e[D - 1]);
                let t2 = n3.cross(&e3);
                basis = [e, SVector::from_fn(|i, _| t2[i])];
            } else {
                basis[0] = (xb - xa).normalize();
            }
            ([1.0 - t, t, 0.0], basis)
        }
        Feature::Face(a, b, c) => {
            let v = |i: u32| {
                nalgebra::Vector3::new(
                    boundary[i as usize][0],
                    boundary[i as usize][1],
                    boundary[i as usize][D - 1],
                )
            };
            let (p3, t0, t1, t2) = (
                nalgebra::Vector3::new(p[0], p[1], p[D - 1]),
                v(a),
                v(b),
                v(c),
            );
            let (b1, b2) = point_triangle::barycentric(&p3, &t0, &t1, &t2).unwrap_or((0.0, 0.0));
            let e1 = (t1 - t0).normalize();
            let nt = (t1 - t0).cross(&(t2 - t0));
            let u2 = nt.cross(&e1).normalize();
            (
                [1.0 - b1 - b2, b1, b2],
                [
                    SVector::from_fn(|i, _| e1[i]),
                    SVector::from_fn(|i, _| u2[i]),
                ],
            )
        }
    }
}

/// Build the lagged friction terms from the contact terms at the lagged state.
///
/// A term's normal force is `λ = −w b'(d)`. The duplicate-removal terms of the barrier (BFEMP
/// eqs. 31–32: an edge or vertex subtracted where the facets around it both count a particle)
/// have negative weights: each is netted against the particle's positive terms whose features
/// contain its vertices ([`net_normal_forces`]), so that a facet term entering or leaving near
/// a concave edge changes the normal forces continuously, as the barrier does, instead of
/// adding or removing a whole λ. Terms with no positive force left are not lagged. `terms` hold each particle's terms
/// together (as [`ContactPotential::collect_terms`] writes them).
pub fn lag<const D: usize>(
    potential: &ContactPotential<D>,
    terms: &[ContactTerm],
    particles: &[SVector<f64, D>],
    boundary: &[SVector<f64, D>],
) -> Vec<FrictionTerm<D>> {
    let lambda = net_normal_forces(potential, terms);
    terms
        .par_iter()
        .zip(lambda.par_iter())
        .filter_map(|(t, &lambda)| {
            if !(lambda > 0.0) {
                return None;
            }
            let p = &particles[t.particle as usize];
            let (beta, basis) = closest_point_frame(p, t.feature, boundary);
            let (vertices, nv) = t.feature.vertices();
            Some(FrictionTerm {
                particle: t.particle,
                vertices,
                n: nv + 1,
                beta,
                basis,
                lambda,
            })
        })
        .collect()
}

/// Each term's normal force `−w b'(d)`, the duplicate-removal (negative) ones netted against
/// the particle's positive terms around them ([`lag`]); a netted or negative force is ≤ 0.
///
/// A subtracted force `λ_s` (its feature's vertices all on each term `i` of the group `G`
/// around it, `λ_i ≥ λ_s` as `d_i ≤ d_s`) leaves the group `Σ_G λ_i − λ_s`, shared as
/// `e_i + (Σ_G λ_i − λ_s − Σ e) e_i / Σ e` with the excesses `e_i = max(0, λ_i − λ_s)`: a term
/// whose region ends at the subtracted feature (`d_i = d_s`) keeps nothing, and the shares
/// change continuously with the distances (equal shares if every excess is 0).
pub fn net_normal_forces<const D: usize>(
    potential: &ContactPotential<D>,
    terms: &[ContactTerm],
) -> Vec<f64> {
    let mut net: Vec<f64> = terms
        .par_iter()
        .map(|t| -t.weight * potential.barrier.first(t.sq_dist.sqrt()))
        .collect();
    let mut group: Vec<usize> = Vec::new();
    let mut start = 0;
    while start < terms.len() {
        let q = terms[start].particle;
        let end = terms[start..]
            .iter()
            .position(|t| t.particle != q)
            .map_or(terms.len(), |k| start + k);
        for j in start..end {
            let sub = -net[j];
            if !(sub > 0.0) {
                continue;
            }
            let (inner, ni) = terms[j].feature.vertices();
            group.clear();
            group.extend((start..end).filter(|&i| {
                let (outer, no) = terms[i].feature.vertices();
                net[i] > 0.0 && no > ni && inner[..ni].iter().all(|v| outer[..no].contains(v))
            }));
            if group.is_empty() {
                continue;
            }
            let total: f64 = group.iter().map(|&i| net[i]).sum();
            let left = (total - sub).max(0.0);
            let excess: f64 = group.iter().map(|&i| (net[i] - sub).max(0.0)).sum();
            for &i in &group {
                let e = (net[i] - sub).max(0.0);
                net[i] = if excess > 0.0 {
                    e + (left - excess).max(0.0) * e / excess
                } else {
                    left / group.len() as f64
                };
            }
        }
        start = end;
    }
    net
}

impl<const D: usize> FrictionTerm<D> {
    /// Relative tangential displacement `u = Tᵀ(Δx_q − Σ β_i Δx_i)` (first `D − 1` entries).
    #[inline]
    pub fn tangential_displacement(
        &self,
        dxp: &[SVector<f64, D>],
        dxb: &[SVector<f64, D>],
    ) -> [f64; 2] {
        let mut rel = dxp[self.particle as usize];
        for i in 0..self.n - 1 {
            rel -= dxb[self.vertices[i] as usize] * self.beta[i];
        }
        [
            self.basis[0].dot(&rel),
            if D == 3 { self.basis[1].dot(&rel) } else { 0.0 },
        ]
    }
}

/// `D(x) = Σ μ λ f₀(|u|)` for particle displacements `dxp` and boundary displacements `dxb`.
pub fn energy<const D: usize>(
    params: &FrictionParams,
    terms: &[FrictionTerm<D>],
    dxp: &[SVector<f64, D>],
    dxb: &[SVector<f64, D>],
) -> f64 {
    let eps = params.eps();
    // Summed in fixed chunks, in order: the same bits on any number of threads (rayon's own
    // `sum` splits by thread count and work stealing).
    terms
        .par_chunks(crate::SUM_CHUNK)
        .map(|chunk| {
            chunk
                .iter()
                .map(|t| {
                    let u = t.tangential_displacement(dxp, dxb);
                    params.mu * t.lambda * f0((u[0] * u[0] + u[1] * u[1]).sqrt(), eps)
                })
                .sum::<f64>()
        })
        .collect::<Vec<f64>>()
        .into_iter()
        .sum()
}

/// Gradient and Hessian (PSD by construction) of every term, into `out` (cleared).
pub fn derivatives<const D: usize>(
    params: &FrictionParams,
    terms: &[FrictionTerm<D>],
    dxp: &[SVector<f64, D>],
    dxb: &[SVector<f64, D>],
    out: &mut Vec<TermDerivatives<D>>,
) {
    model_derivatives(params, terms, dxp, dxb, &[], out);
}

/// Which terms a step along a direction carries through their stick zone: sliding now
/// (`|u| ≥ ε`) and past the zone's centre at the step's end (`u · (u + Δu) < 0`, with
/// `Δu` the tangential displacement of the direction's increments `pxp`, `pxb`), into `out`
/// (one flag per term); returns how many.
///
/// Along such a step the term's Taylor model — a constant force `μλ û` with no curvature
/// along the slip — overshoots its kink, and a line search can only cut the whole step: a
/// solve then creeps towards the stick zone over many short steps. Modelled as stuck
/// ([`model_derivatives`]), the term's next direction lands in the zone instead.
pub fn carried_through_stick<const D: usize>(
    params: &FrictionParams,
    terms: &[FrictionTerm<D>],
    (dxp, dxb): (&[SVector<f64, D>], &[SVector<f64, D>]),
    (pxp, pxb): (&[SVector<f64, D>], &[SVector<f64, D>]),
    out: &mut Vec<bool>,
) -> usize {
    let eps = params.eps();
    terms
        .par_iter()
        .with_min_len(256)
        .map(|t| {
            let u = t.tangential_displacement(dxp, dxb);
            let du = t.tangential_displacement(pxp, pxb);
            let y = (u[0] * u[0] + u[1] * u[1]).sqrt();
            y >= eps && u[0] * (u[0] + du[0]) + u[1] * (u[1] + du[1]) < 0.0
        })
        .collect_into_vec(out);
    out.iter().filter(|&&s| s).count()
}

/// [`derivatives`], with the terms flagged in `stuck` (empty: none) modelled as sticking: the
/// quadratic `μλ |u|²/ε` of the stick zone's centre (the curvature `f₁/y = f₁' = 2/ε` of
/// `y → 0` in every tangential direction, and its gradient `μλ (2/ε) T u`) instead of the
/// Taylor expansion at `u`. The model's Hessian block is at least the true one
/// (`f₁/y, f₁' ≤ 2/ε`), so a matrix that is positive definite stays so.
pub fn model_derivatives<const D: usize>(
    params: &FrictionParams,
    terms: &[FrictionTerm<D>],
    dxp: &[SVector<f64, D>],
    dxb: &[SVector<f64, D>],
    stuck: &[bool],
    out: &mut Vec<TermDerivatives<D>>,
) {
    let eps = params.eps();
    terms
        .par_iter()
        .enumerate()
        .with_min_len(256)
        .map(|(k, t)| {
            let u = t.tangential_displacement(dxp, dxb);
            let y = if stuck.get(k).copied().unwrap_or(false) {
                0.0
            } else {
                (u[0] * u[0] + u[1] * u[1]).sqrt()
            };
            let s = params.mu * t.lambda;
            let c = [1.0, -t.beta[0], -t.beta[1], -t.beta[2]];
            // Force direction in space: T u, scaled.
            let tu = t.basis[0] * u[0]
                + if D == 3 {
                    t.basis[1] * u[1]
                } else {
                    SVector::zeros()
                };
            let g = tu * (s * f1_over_y(y, eps));
            // M in the tangent frame, then T M Tᵀ in space.
            let tmt = if D == 2 {
                t.basis[0] * t.basis[0].transpose() * f1_prime(y, eps)
            } else {
                let (a, b) = (f1_prime(y, eps), f1_over_y(y, eps));
                let (uh0, uh1) = if y > 0.0 {
                    (u[0] / y, u[1] / y)
                } else {
                    (1.0, 0.0)
                };
                let m = nalgebra::Matrix2::new(
                    a * uh0 * uh0 + b * (1.0 - uh0 * uh0),
                    (a - b) * uh0 * uh1,
                    (a - b) * uh0 * uh1,
                    a * uh1 * uh1 + b * (1.0 - uh1 * uh1),
                );
                let mut r = SMatrix::<f64, D, D>::zeros();
                for i in 0..2 {
                    for j in 0..2 {
                        r += t.basis[i] * t.basis[j].transpose() * m[(i, j)];
                    }
                }
                r
            };
            let mut d = TermDerivatives {
                particle: t.particle,
                vertices: t.vertices,
                n: t.n,
                grad: [SVector::zeros(); 4],
                hess: [[SMatrix::zeros(); 4]; 4],
            };
            for a in 0..t.n {
                d.grad[a] = g * c[a];
                for b in 0..t.n {
                    d.hess[a][b] = tmt * (s * c[a] * c[b]);
                }
            }
            d
        })
        .collect_into_vec(out);
}
