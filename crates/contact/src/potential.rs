//! The BFEMP contact potential between particles and a boundary mesh (eqs. 28–32).
//!
//! For particle `q` with weight `ω_q` (a boundary measure, [`particle_weight`]):
//!
//! ```text
//! 2D:  B_q = ω_q [ Σ_{edges e} b(d_PE(q, e)) − Σ_{vertices k} (η_k − 1) b(d_PP(q, k)) ]
//! 3D:  B_q = ω_q [ Σ_{triangles t} b(d_PT) − Σ_{edges e} (η_e − 1) b(d_PE) + Σ_{vertices k} c_k b(d_PP) ]
//! ```
//!
//! `η` counts incident boundary facets; in 3D the vertex coefficient is
//! `c_k = 1 − (#triangles at k) + Σ_{edges e ∋ k} (η_e − 1)` — exactly 1 on a closed surface, the
//! value that makes a particle whose closest feature is vertex `k` count `b(d_PP)` once. (The
//! paper states `+b(d_PP)` over "interior nodes"; this is the general form.)
//!
//! **Canonical features.** A point–edge distance in a vertex region *is* the point–point distance
//! to that vertex, with the same derivatives; likewise point–triangle in an edge or vertex
//! region. So every term is first reduced to its closest feature (vertex, edge interior, face
//! interior) and coefficients of equal features are summed. On a closed 2D polyline, a particle
//! nearest to a vertex gets `(+1 +1 −1) = 1` term with that vertex. Each remaining term's Hessian
//! is made PSD on its small stencil (2–4 points), by default by clipping the exact Hessian's
//! negative eigenvalues, optionally as `ω b''(d) ∇d∇dᵀ` (Gauss–Newton in the distance,
//! [`BarrierHessian`]); since equal distance functions were merged first, doing so term by
//! term loses nothing where the duplicates cancel.
//!
//! **Units.** `κ` in Pa, `d` in m, `ω_q` in m (2D, per unit thickness) or m² (3D): `κ ω b` is an
//! energy (per unit thickness in 2D), as required inside `2αβΔt²(Ψ + B + D)`.

use nalgebra::{SMatrix, SVector, SymmetricEigen};
use rayon::prelude::*;

use crate::broad_phase::Candidates;
use crate::distance::point_edge::{self, PointEdgeRegion};
use crate::distance::point_point;
use crate::distance::point_triangle::{self, PointTriangleRegion};
use crate::{ContactError, LogBarrier};

/// Per-particle boundary measure `ω_q` from its volume `V_q`: the largest cross-section of a
/// disk/ball of that volume — 2D `2√(V_q/π)` (a length), 3D `π (3V_q/(4π))^{2/3}` (an area).
pub fn particle_weight<const D: usize>(volume: f64) -> f64 {
    if D == 2 {
        2.0 * (volume / std::f64::consts::PI).sqrt()
    } else {
        std::f64::consts::PI * (3.0 * volume / (4.0 * std::f64::consts::PI)).powf(2.0 / 3.0)
    }
}

/// A closest feature of the boundary (indices into the boundary vertex array).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Feature {
    /// A vertex.
    Vertex(u32),
    /// The interior of an edge.
    Edge(u32, u32),
    /// The interior of a triangle (3D).
    Face(u32, u32, u32),
}

impl Feature {
    /// Its vertices (1, 2 or 3) and their number.
    #[inline]
    pub fn vertices(&self) -> ([u32; 3], usize) {
        match *self {
            Feature::Vertex(a) => ([a, 0, 0], 1),
            Feature::Edge(a, b) => ([a, b, 0], 2),
            Feature::Face(a, b, c) => ([a, b, c], 3),
        }
    }
}

/// Boundary connectivity and the duplicate-removal coefficients of eqs. 31–32.
#[derive(Clone, Debug)]
pub struct BoundaryTopology<const D: usize> {
    facets: Vec<[u32; 3]>,
    vertex_coeff: Vec<f64>,
    /// 3D: `−(η_e − 1)` for the edges `(f0,f1), (f1,f2), (f2,f0)` of each facet.
    edge_coeff: Vec<[f64; 3]>,
    num_vertices: usize,
}

impl<const D: usize> BoundaryTopology<D> {
    /// From boundary facets (the first `D` entries of each: edges in 2D, triangles in 3D) over
    /// `num_vertices` boundary vertices. Facet orientation does not matter for contact.
    pub fn new(facets: &[[u32; 3]], num_vertices: usize) -> Result<Self, ContactError> {
        const { assert!(D == 2 || D == 3) };
        for (f, fa) in facets.iter().enumerate() {
            let v = &fa[..D];
            if let Some(&bad) = v.iter().find(|&&i| i as usize >= num_vertices) {
                return Err(ContactError::BadFacet {
                    facet: f,
                    reason: format!("references vertex {bad} of {num_vertices}"),
                });
            }
            for i in 0..D {
                for j in i + 1..D {
                    if v[i] == v[j] {
                        return Err(ContactError::BadFacet {
                            facet: f,
                            reason: "repeats a vertex".into(),
                        });
                    }
                }
            }
        }
        let mut vcount = vec![0u32; num_vertices];
        for fa in facets {
            for &v in &fa[..D] {
                vcount[v as usize] += 1;
            }
        }
        let mut vertex_coeff = vec![0.0; num_vertices];
        let mut edge_coeff = Vec::new();
        if D == 2 {
            for v in 0..num_vertices {
                vertex_coeff[v] = 1.0 - vcount[v] as f64;
            }
        } else {
            let mut ecount: rustc_hash::FxHashMap<(u32, u32), u32> = Default::default();
            for fa in facets {
                for k in 0..3 {
                    let (a, b) = (fa[k], fa[(k + 1) % 3]);
                    *ecount.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                }
            }
            for v in 0..num_vertices {
                vertex_coeff[v] = 1.0 - vcount[v] as f64;
            }
            for (&(a, b), &n) in &ecount {
                let extra = n as f64 - 1.0;
                vertex_coeff[a as usize] += extra;
                vertex_coeff[b as usize] += extra;
            }
            edge_coeff = facets
                .iter()
                .map(|fa| {
                    std::array::from_fn(|k| {
                        let (a, b) = (fa[k], fa[(k + 1) % 3]);
                        -(ecount[&(a.min(b), a.max(b))] as f64 - 1.0)
                    })
                })
                .collect();
        }
        Ok(Self {
            facets: facets.to_vec(),
            vertex_coeff,
            edge_coeff,
            num_vertices,
        })
    }

    /// The facets.
    pub fn facets(&self) -> &[[u32; 3]] {
        &self.facets
    }

    /// Number of boundary vertices.
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Coefficient of the point–point term of each vertex (2D: `1 − η_k`).
    pub fn vertex_coefficients(&self) -> &[f64] {
        &self.vertex_coeff
    }
}

/// Per-point vectors of a stencil of up to 4 points.
pub type Blocks<const D: usize> = [SVector<f64, D>; 4];
/// Per-point-pair matrices of a stencil of up to 4 points.
pub type BlockMatrix<const D: usize> = [[SMatrix<f64, D, D>; 4]; 4];

/// One active term: `weight · b(d)` between a particle and a boundary feature, with
/// `weight = ω_q × (net coefficient)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactTerm {
    /// Particle index.
    pub particle: u32,
    /// Closest feature.
    pub feature: Feature,
    /// `ω_q` times the summed coefficient of this feature.
    pub weight: f64,
    /// Squared distance at which it was collected.
    pub sq_dist: f64,
}

/// Gradient and PSD-projected Hessian of one term on its stencil: the particle first, then the
/// feature's vertices (`n = 1 + #vertices` points).
#[derive(Clone, Copy, Debug)]
pub struct TermDerivatives<const D: usize> {
    /// Particle index.
    pub particle: u32,
    /// Boundary vertex indices of the feature (first `n − 1` valid).
    pub vertices: [u32; 3],
    /// Stencil size (2, 3 or 4).
    pub n: usize,
    /// Gradient blocks.
    pub grad: [SVector<f64, D>; 4],
    /// Hessian blocks, `hess[i][j]` for stencil points `i`, `j`.
    pub hess: [[SMatrix<f64, D, D>; 4]; 4],
}

/// Which PSD Hessian [`ContactPotential::derivatives`] gives for a term `ω b(d(x))`.
///
/// The exact Hessian is `ω [b''(d) ∇d ∇dᵀ + b'(d) ∇²d]`. Its first part is PSD (`b'' > 0`); the
/// second is not (`b' < 0`, and `∇²d` is indefinite when the facet can move and turn).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BarrierHessian {
    /// The exact Hessian with its negative eigenvalues set to zero on the term's stencil (the
    /// IPC default, and ours). Clipping adds curvature that the energy does not have, mostly
    /// tangential to the facet, so Newton converges linearly while particles slide along it.
    #[default]
    Projected,
    /// `ω b''(d) ∇d ∇dᵀ` (Gauss–Newton in the distance): rank one, PSD by construction, no
    /// eigensolver; exact for a point against a fixed flat facet. It drops the distance's
    /// curvature: half the Newton iterations of `Projected` on the §6.7 twist (particles sliding
    /// under a stiff shell), but on the §6.1 rings and the §6.2 sine boundary some steps then
    /// oscillate between features and miss the iteration limit (`docs/performance.md`).
    GaussNewton,
}

/// The contact potential: barrier plus boundary topology.
#[derive(Clone, Debug)]
pub struct ContactPotential<const D: usize> {
    /// The barrier.
    pub barrier: LogBarrier,
    /// The boundary.
    pub topology: BoundaryTopology<D>,
    /// The Hessian approximation (default: projected).
    pub hessian: BarrierHessian,
}

/// Squared distance and canonical feature of a particle against one facet.
#[inline]
fn facet_feature<const D: usize>(
    p: &SVector<f64, D>,
    f: &[u32; 3],
    x: &[SVector<f64, D>],
) -> (f64, Feature) {
    if D == 2 {
        let (a, b) = (&x[f[0] as usize], &x[f[1] as usize]);
        let r = point_edge::region(p, a, b);
        let s = point_edge::sq_dist_in(r, p, a, b);
        let feat = match r {
            PointEdgeRegion::V0 => Feature::Vertex(f[0]),
            PointEdgeRegion::V1 => Feature::Vertex(f[1]),
            PointEdgeRegion::Interior => Feature::Edge(f[0], f[1]),
        };
        (s, feat)
    } else {
        let p3 = to3(p);
        let (a, b, c) = (
            to3(&x[f[0] as usize]),
            to3(&x[f[1] as usize]),
            to3(&x[f[2] as usize]),
        );
        let r = point_triangle::region(&p3, &a, &b, &c);
        let s = point_triangle::sq_dist_in(r, &p3, &a, &b, &c);
        use PointTriangleRegion::*;
        let feat = match r {
            V0 => Feature::Vertex(f[0]),
            V1 => Feature::Vertex(f[1]),
            V2 => Feature::Vertex(f[2]),
            E01 => Feature::Edge(f[0], f[1]),
            E12 => Feature::Edge(f[1], f[2]),
            E20 => Feature::Edge(f[2], f[0]),
            Face => Feature::Face(f[0], f[1], f[2]),
        };
        (s, feat)
    }
}

#[inline]
fn to3<const D: usize>(v: &SVector<f64, D>) -> nalgebra::Vector3<f64> {
    nalgebra::Vector3::new(v[0], v[1], if D == 3 { v[D - 1] } else { 0.0 })
}

#[inline]
fn from3<const D: usize>(v: &nalgebra::Vector3<f64>) -> SVector<f64, D> {
    SVector::from_fn(|a, _| v[a])
}

/// Same feature regardless of the orientation an edge was visited in.
#[inline]
fn canonical(f: Feature) -> Feature {
    match f {
        Feature::Edge(a, b) if a > b => Feature::Edge(b, a),
        other => other,
    }
}

/// Per-thread scratch for collecting a particle's terms.
#[derive(Default)]
struct Scratch {
    terms: Vec<(Feature, f64, f64)>,
    seen_vertices: Vec<u32>,
    seen_edges: Vec<(u32, u32)>,
}

impl Scratch {
    fn add(&mut self, f: Feature, coeff: f64, s: f64) {
        let f = canonical(f);
        if let Some(t) = self.terms.iter_mut().find(|t| t.0 == f) {
            t.1 += coeff;
        } else {
            self.terms.push((f, coeff, s));
        }
    }
}

impl<const D: usize> ContactPotential<D> {
    /// A potential for the given barrier and boundary.
    pub fn new(barrier: LogBarrier, topology: BoundaryTopology<D>) -> Self {
        Self {
            barrier,
            topology,
            hessian: BarrierHessian::default(),
        }
    }

    /// The same potential with Hessian approximation `hessian`.
    pub fn with_hessian(mut self, hessian: BarrierHessian) -> Self {
        self.hessian = hessian;
        self
    }

    /// Collect the active terms (`d < d̂`) of every particle from its candidate facets, into
    /// `out` (cleared). Fails with [`ContactError::Penetration`] if a particle is at distance 0
    /// from a candidate facet, or on non-finite input.
    pub fn collect_terms(
        &self,
        particles: &[SVector<f64, D>],
        weights: &[f64],
        boundary: &[SVector<f64, D>],
        candidates: &Candidates,
        out: &mut Vec<ContactTerm>,
    ) -> Result<(), ContactError> {
        crate::check_len("particle weights", particles.len(), weights.len())?;
        crate::check_len(
            "boundary positions",
            self.topology.num_vertices,
            boundary.len(),
        )?;
        crate::check_len(
            "candidate lists",
            particles.len(),
            candidates.num_particles(),
        )?;
        // Particles in chunks of a fixed size, each chunk's terms into one vector (a few dozen
        // allocations per call, none per particle), joined in particle order: the same terms
        // in the same order whatever the number of threads.
        const CHUNK: usize = 512;
        let n = particles.len();
        let parts: Vec<Result<Vec<ContactTerm>, ContactError>> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map_init(Scratch::default, |sc, c| {
                let mut terms = Vec::new();
                for q in c * CHUNK..n.min((c + 1) * CHUNK) {
                    let cands = candidates.of(q);
                    if !cands.is_empty() {
                        self.particle_terms(
                            q,
                            &particles[q],
                            weights[q],
                            cands,
                            boundary,
                            sc,
                            &mut terms,
                        )?;
                    }
                }
                Ok(terms)
            })
            .collect();
        out.clear();
        for part in parts {
            out.extend_from_slice(&part?);
        }
        Ok(())
    }

    /// The active terms of particle `q` at `p` (weight `w`) against its candidate facets,
    /// appended to `out`.
    #[allow(clippy::too_many_arguments)]
    fn particle_terms(
        &self,
        q: usize,
        p: &SVector<f64, D>,
        w: f64,
        cands: &[u32],
        boundary: &[SVector<f64, D>],
        sc: &mut Scratch,
        out: &mut Vec<ContactTerm>,
    ) -> Result<(), ContactError> {
        let dhat2 = self.barrier.dhat * self.barrier.dhat;
        let topo = &self.topology;
        if p.iter().any(|c| !c.is_finite()) {
            return Err(ContactError::NonFinite {
                what: "particle position",
                index: q,
            });
        }
        sc.terms.clear();
        sc.seen_vertices.clear();
        sc.seen_edges.clear();
        for &fi in cands {
            let fa = &topo.facets[fi as usize];
            let (s, feat) = facet_feature(p, fa, boundary);
            if !(s > 0.0) {
                return Err(ContactError::Penetration {
                    particle: q,
                    facet: fi as usize,
                    distance: s.max(0.0).sqrt(),
                });
            }
            if s < dhat2 {
                sc.add(feat, 1.0, s);
            }
            if D == 3 {
                for k in 0..3 {
                    let (a, b) = (fa[k], fa[(k + 1) % 3]);
                    let key = (a.min(b), a.max(b));
                    if sc.seen_edges.contains(&key) {
                        continue;
                    }
                    sc.seen_edges.push(key);
                    let c = topo.edge_coeff[fi as usize][k];
                    if c == 0.0 {
                        continue;
                    }
                    let (xa, xb) = (&boundary[a as usize], &boundary[b as usize]);
                    let r = point_edge::region(p, xa, xb);
                    let se = point_edge::sq_dist_in(r, p, xa, xb);
                    if se < dhat2 {
                        let feat = match r {
                            PointEdgeRegion::V0 => Feature::Vertex(a),
                            PointEdgeRegion::V1 => Feature::Vertex(b),
                            PointEdgeRegion::Interior => Feature::Edge(a, b),
                        };
                        sc.add(feat, c, se);
                    }
                }
            }
            for &v in &fa[..D] {
                if sc.seen_vertices.contains(&v) {
                    continue;
                }
                sc.seen_vertices.push(v);
                let c = topo.vertex_coeff[v as usize];
                if c == 0.0 {
                    continue;
                }
                let sv = point_point::sq_dist(p, &boundary[v as usize]);
                if sv < dhat2 {
                    sc.add(Feature::Vertex(v), c, sv);
                }
            }
        }
        out.extend(
            sc.terms
                .iter()
                .filter(|t| t.1 != 0.0)
                .map(|&(feature, c, s)| ContactTerm {
                    particle: q as u32,
                    feature,
                    weight: w * c,
                    sq_dist: s,
                }),
        );
        Ok(())
    }

    /// `B = Σ_terms weight · b(d)`.
    pub fn energy(&self, terms: &[ContactTerm]) -> f64 {
        // Fixed chunks summed in order: the same bits on any number of threads.
        terms
            .par_chunks(crate::SUM_CHUNK)
            .map(|chunk| {
                chunk
                    .iter()
                    .map(|t| t.weight * self.barrier.value(t.sq_dist.sqrt()))
                    .sum::<f64>()
            })
            .collect::<Vec<f64>>()
            .into_iter()
            .sum()
    }

    /// Squared distance of a particle to a feature, with gradient and Hessian on the stencil
    /// `(particle, feature vertices…)`.
    pub fn feature_sq_dist(
        p: &SVector<f64, D>,
        feature: Feature,
        boundary: &[SVector<f64, D>],
    ) -> (f64, Blocks<D>, BlockMatrix<D>) {
        Self::feature_sq_dist_with(p, feature, boundary, true)
    }

    /// [`Self::feature_sq_dist`], the Hessian left zero unless `hessian`.
    fn feature_sq_dist_with(
        p: &SVector<f64, D>,
        feature: Feature,
        boundary: &[SVector<f64, D>],
        hessian: bool,
    ) -> (f64, Blocks<D>, BlockMatrix<D>) {
        let mut g = [SVector::zeros(); 4];
        let mut h = [[SMatrix::zeros(); 4]; 4];
        match feature {
            Feature::Vertex(a) => {
                let q = &boundary[a as usize];
                let gg = point_point::sq_dist_grad(p, q);
                g[..2].copy_from_slice(&gg);
                if hessian {
                    let hh = point_point::sq_dist_hess::<D>();
                    for i in 0..2 {
                        h[i][..2].copy_from_slice(&hh[i]);
                    }
                }
                (point_point::sq_dist(p, q), g, h)
            }
            Feature::Edge(a, b) => {
                let (xa, xb) = (&boundary[a as usize], &boundary[b as usize]);
                let r = PointEdgeRegion::Interior;
                let gg = point_edge::sq_dist_grad_in(r, p, xa, xb);
                g[..3].copy_from_slice(&gg);
                if hessian {
                    let hh = point_edge::sq_dist_hess_in(r, p, xa, xb);
                    for i in 0..3 {
                        h[i][..3].copy_from_slice(&hh[i]);
                    }
                }
                (point_edge::sq_dist_in(r, p, xa, xb), g, h)
            }
            Feature::Face(a, b, c) => {
                let (p3, xa, xb, xc) = (
                    to3(p),
                    to3(&boundary[a as usize]),
                    to3(&boundary[b as usize]),
                    to3(&boundary[c as usize]),
                );
                let r = PointTriangleRegion::Face;
                let gg = point_triangle::sq_dist_grad_in(r, &p3, &xa, &xb, &xc);
                for i in 0..4 {
                    g[i] = from3(&gg[i]);
                }
                if hessian {
                    let hh = point_triangle::sq_dist_hess_in(r, &p3, &xa, &xb, &xc);
                    for i in 0..4 {
                        for j in 0..4 {
                            h[i][j] = SMatrix::from_fn(|r, c| hh[i][j][(r, c)]);
                        }
                    }
                }
                (point_triangle::sq_dist_in(r, &p3, &xa, &xb, &xc), g, h)
            }
        }
    }

    /// Gradient and PSD Hessian (see [`BarrierHessian`]) of every term, in parallel, into `out`
    /// (cleared).
    pub fn derivatives(
        &self,
        terms: &[ContactTerm],
        particles: &[SVector<f64, D>],
        boundary: &[SVector<f64, D>],
        out: &mut Vec<TermDerivatives<D>>,
    ) {
        self.derivatives_as(self.hessian, false, terms, particles, boundary, out);
    }

    /// Gradient and **exact** Hessian `ω [b''(d) ∇d ∇dᵀ + b'(d) ∇²d]` of every term (not
    /// projected, whatever [`Self::hessian`] says; indefinite in general), in parallel, into
    /// `out` (cleared). For Newton iterations that use the exact Hessian when the assembled
    /// system is positive definite.
    pub fn exact_derivatives(
        &self,
        terms: &[ContactTerm],
        particles: &[SVector<f64, D>],
        boundary: &[SVector<f64, D>],
        out: &mut Vec<TermDerivatives<D>>,
    ) {
        self.derivatives_as(
            BarrierHessian::Projected,
            true,
            terms,
            particles,
            boundary,
            out,
        );
    }

    fn derivatives_as(
        &self,
        mode: BarrierHessian,
        exact_only: bool,
        terms: &[ContactTerm],
        particles: &[SVector<f64, D>],
        boundary: &[SVector<f64, D>],
        out: &mut Vec<TermDerivatives<D>>,
    ) {
        terms
            .par_iter()
            .with_min_len(256)
            .map(|t| {
                let p = &particles[t.particle as usize];
                let exact = mode == BarrierHessian::Projected;
                let (s, gs, hs) = Self::feature_sq_dist_with(p, t.feature, boundary, exact);
                let (_, bs, bss) = self.barrier.sq_derivatives(s);
                let (vertices, nv) = t.feature.vertices();
                let n = nv + 1;
                let mut d = TermDerivatives {
                    particle: t.particle,
                    vertices,
                    n,
                    grad: [SVector::zeros(); 4],
                    hess: [[SMatrix::zeros(); 4]; 4],
                };
                for i in 0..n {
                    d.grad[i] = gs[i] * (t.weight * bs);
                }
                match mode {
                    BarrierHessian::GaussNewton => {
                        // b''(d) ∇d ∇dᵀ with ∇d = ∇s / (2d): b''(d) / (4s) ∇s ∇sᵀ, weighted.
                        let b2 = self.barrier.second(s.sqrt());
                        let c = (b2 / (4.0 * s) * t.weight).max(0.0);
                        for i in 0..n {
                            for j in 0..n {
                                d.hess[i][j] = gs[i] * gs[j].transpose() * c;
                            }
                        }
                    }
                    BarrierHessian::Projected => {
                        for i in 0..n {
                            for j in 0..n {
                                d.hess[i][j] =
                                    (gs[i] * gs[j].transpose() * bss + hs[i][j] * bs) * t.weight;
                            }
                        }
                        if !exact_only {
                            project_psd(&mut d.hess, n * D);
                        }
                    }
                }
                d
            })
            .collect_into_vec(out);
    }
}

/// Project the symmetric matrix made of the top-left `n×n` blocks of `h` (`n = m/D` stencil
/// points) onto the PSD cone: eigenvalues below zero set to zero.
///
/// Contact energies are invariant under translating the whole stencil, so the `D` translation
/// directions are exact null vectors of the Hessian. With an orthonormal basis `Q` of their
/// complement (Helmert contrasts ⊗ `I_D`), `H = Q (QᵀHQ) Qᵀ` and the projection of `H` is
/// `Q proj(QᵀHQ) Qᵀ` — exactly the same result from an `(n−1)D`-sized eigenproblem
/// (9×9 instead of 12×12 for point–triangle). Two-point stencils need no eigensolver at all:
/// `QᵀHQ` is `D×D`, and is projected in closed form for `D = 2` and by a 3×3 solve for `D = 3`.
pub fn project_psd<const D: usize>(h: &mut [[SMatrix<f64, D, D>; 4]; 4], m: usize) {
    let n = m / D;
    // Helmert contrasts: row k (k = 1..n−1) = (1, …, 1, −k, 0, …)/√(k(k+1)), over n points.
    let mut v = [[0.0f64; 4]; 3];
    for k in 1..n {
        let c = 1.0 / ((k * (k + 1)) as f64).sqrt();
        for i in 0..k {
            v[k - 1][i] = c;
        }
        v[k - 1][k] = -(k as f64) * c;
    }
    let r = (n - 1) * D;
    // A = Qᵀ H Q, entry ((k, a), (l, b)) = Σ_ij v_ki v_lj H_ij[a][b].
    let mut a = [[0.0f64; 9]; 9];
    for k in 0..n - 1 {
        for l in 0..n - 1 {
            let mut blk = SMatrix::<f64, D, D>::zeros();
            for i in 0..n {
                if v[k][i] == 0.0 {
                    continue;
                }
                for j in 0..n {
                    if v[l][j] != 0.0 {
                        blk += h[i][j] * (v[k][i] * v[l][j]);
                    }
                }
            }
            for x in 0..D {
                for y in 0..D {
                    a[k * D + x][l * D + y] = blk[(x, y)];
                }
            }
        }
    }
    macro_rules! proj {
        ($M:literal) => {{
            let am = SMatrix::<f64, $M, $M>::from_fn(|x, y| 0.5 * (a[x][y] + a[y][x]));
            let e = SymmetricEigen::new(am);
            if e.eigenvalues.min() >= 0.0 {
                return;
            }
            let l = e.eigenvalues.map(|x| x.max(0.0));
            let b = e.eigenvectors
                * SMatrix::<f64, $M, $M>::from_diagonal(&l)
                * e.eigenvectors.transpose();
            for x in 0..$M {
                for y in 0..$M {
                    a[x][y] = b[(x, y)];
                }
            }
        }};
    }
    match r {
        2 => proj!(2),
        3 => proj!(3),
        4 => proj!(4),
        6 => proj!(6),
        9 => proj!(9),
        _ => unreachable!("stencils have 2–4 points in 2D or 3D"),
    }
    // H = Q A Qᵀ: H_ij = Σ_kl v_ki v_lj A_kl.
    for i in 0..n {
        for j in 0..n {
            let mut blk = SMatrix::<f64, D, D>::zeros();
            for k in 0..n - 1 {
                for l in 0..n - 1 {
                    let c = v[k][i] * v[l][j];
                    if c != 0.0 {
                        for x in 0..D {
                            for y in 0..D {
                                blk[(x, y)] += c * a[k * D + x][l * D + y];
                            }
                        }
                    }
                }
            }
            h[i][j] = blk;
        }
    }
}
