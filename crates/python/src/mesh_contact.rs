//! femp's barrier contact over whole meshes (`femp.contact.ContactMesh` in the Python package):
//! points (particles, or another mesh's vertices) against the boundary facets of a mesh —
//! broad-phase candidates, the active terms with their distances and closest features, the
//! potential with its gradient and sparse Hessian, and the CCD-limited largest step of a
//! linear motion. Each call converts its arrays once and releases the GIL for the work, which
//! runs in femp-contact's parallel code (what the BFEMP step runs).

use femp_contact::broad_phase::{Candidates, candidates_swept, candidates_within};
use femp_contact::ccd::{CcdOptions, max_step};
use femp_contact::{
    BarrierHessian, BoundaryTopology, ContactPotential, ContactTerm, Feature, LogBarrier,
    TermDerivatives,
};
use nalgebra::SVector;
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Rows of an (n, D) array, every value finite.
fn rows<const D: usize>(
    a: &PyReadonlyArray2<'_, f64>,
    what: &str,
) -> PyResult<Vec<SVector<f64, D>>> {
    let out = crate::array_rows::<D>(a).map_err(|m| err(format!("{what}: {m}")))?;
    if let Some(i) = out.iter().position(|r| !r.iter().all(|c| c.is_finite())) {
        return Err(err(format!("{what}: row {i} is not finite")));
    }
    Ok(out)
}

/// One mesh's boundary, its barrier and the buffers its queries reuse.
struct Mesh<const D: usize> {
    potential: ContactPotential<D>,
    x: Vec<SVector<f64, D>>,
    facets: Vec<[u32; 3]>,
    candidates: Candidates,
    terms: Vec<ContactTerm>,
    derivatives: Vec<TermDerivatives<D>>,
}

impl<const D: usize> Mesh<D> {
    fn new(
        x: Vec<SVector<f64, D>>,
        facets: &PyReadonlyArray2<'_, i64>,
        barrier: LogBarrier,
        hessian: BarrierHessian,
    ) -> PyResult<Self> {
        let f = facets.as_array();
        if f.ncols() != D {
            return Err(err(format!(
                "facets: shape ({}, {}), expected (m, {D}) vertex indices ({})",
                f.nrows(),
                f.ncols(),
                if D == 2 { "edges" } else { "triangles" }
            )));
        }
        let mut list = Vec::with_capacity(f.nrows());
        for i in 0..f.nrows() {
            let mut fa = [0u32; 3];
            for k in 0..D {
                let v = f[(i, k)];
                fa[k] = u32::try_from(v)
                    .map_err(|_| err(format!("facets[{i}]: vertex index {v} out of range")))?;
            }
            list.push(fa);
        }
        let topology = BoundaryTopology::<D>::new(&list, x.len()).map_err(err)?;
        Ok(Self {
            potential: ContactPotential::new(barrier, topology).with_hessian(hessian),
            x,
            facets: list,
            candidates: Candidates::default(),
            terms: Vec::new(),
            derivatives: Vec::new(),
        })
    }

    /// The active terms of `points` (weights `w`) against the boundary now.
    fn collect(&mut self, points: &[SVector<f64, D>], w: &[f64]) -> PyResult<()> {
        let dhat = self.potential.barrier.dhat;
        candidates_within(points, &self.x, &self.facets, dhat, &mut self.candidates);
        self.potential
            .collect_terms(points, w, &self.x, &self.candidates, &mut self.terms)
            .map_err(err)
    }
}

enum AnyMesh {
    D2(Box<Mesh<2>>),
    D3(Box<Mesh<3>>),
}

macro_rules! with_mesh {
    ($m:expr, $v:ident => $body:expr) => {
        match $m {
            AnyMesh::D2($v) => $body,
            AnyMesh::D3($v) => $body,
        }
    };
}

/// femp's barrier contact against one mesh's boundary facets (edges in 2D, triangles in 3D):
/// see `femp.contact.ContactMesh`.
#[pyclass(name = "ContactMesh", module = "femp")]
pub(crate) struct PyContactMesh {
    mesh: AnyMesh,
}

fn point_weights(w: Option<&PyReadonlyArray1<'_, f64>>, n: usize) -> PyResult<Vec<f64>> {
    match w {
        None => Ok(vec![1.0; n]),
        Some(w) => {
            let w = w.as_array().to_vec();
            if w.len() != n {
                return Err(err(format!("weights: {} values for {n} points", w.len())));
            }
            if let Some(i) = w.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(err(format!("weights[{i}] = {}: must be ≥ 0", w[i])));
            }
            Ok(w)
        }
    }
}

/// The potential of `points` against `m`: value, term count, gradient ((points + vertices) × D)
/// and the Hessian as COO triplets over the same numbering times D.
type Potential = (f64, usize, Vec<f64>, Vec<i32>, Vec<i32>, Vec<f64>);

fn potential_d<const D: usize>(
    m: &mut Mesh<D>,
    points: &[SVector<f64, D>],
    w: &[f64],
    hessian: bool,
) -> PyResult<Potential> {
    m.collect(points, w)?;
    let value = m.potential.energy(&m.terms);
    m.potential
        .derivatives(&m.terms, points, &m.x, &mut m.derivatives);
    let mut grad = vec![0.0; (points.len() + m.x.len()) * D];
    let mut coo = femp_contact::assembly::Coo::default();
    femp_contact::assembly::assemble(
        &m.derivatives,
        points.len(),
        &mut grad,
        hessian.then_some(&mut coo),
    )
    .map_err(err)?;
    Ok((value, m.terms.len(), grad, coo.rows, coo.cols, coo.values))
}

/// The active terms of `points` against `m`: point, feature kind (1 vertex, 2 edge, 3 face),
/// feature vertices (−1 padded), distance, weight.
type Active = (Vec<i64>, Vec<i64>, Vec<[i64; 3]>, Vec<f64>, Vec<f64>);

fn active_d<const D: usize>(
    m: &mut Mesh<D>,
    points: &[SVector<f64, D>],
    w: &[f64],
) -> PyResult<Active> {
    m.collect(points, w)?;
    let mut out: Active = Default::default();
    for t in &m.terms {
        let (v, k) = t.feature.vertices();
        out.0.push(i64::from(t.particle));
        out.1.push(match t.feature {
            Feature::Vertex(_) => 1,
            Feature::Edge(..) => 2,
            Feature::Face(..) => 3,
        });
        out.2.push(std::array::from_fn(|i| {
            if i < k { i64::from(v[i]) } else { -1 }
        }));
        out.3.push(t.sq_dist.sqrt());
        out.4.push(t.weight);
    }
    Ok(out)
}

/// The largest step of the linear motion `points0 → points1` (the boundary `x → x1`) that
/// keeps every point off every facet, and the limiting (point, facet).
fn max_step_d<const D: usize>(
    m: &mut Mesh<D>,
    p0: &[SVector<f64, D>],
    p1: &[SVector<f64, D>],
    x1: Option<Vec<SVector<f64, D>>>,
) -> (f64, i64, i64) {
    let x1 = x1.unwrap_or_else(|| m.x.clone());
    candidates_swept(p0, p1, &m.x, &x1, &m.facets, 0.0, &mut m.candidates);
    let dp: Vec<SVector<f64, D>> = p0.iter().zip(p1).map(|(a, b)| b - a).collect();
    let dx: Vec<SVector<f64, D>> = m.x.iter().zip(&x1).map(|(a, b)| b - a).collect();
    let (alpha, at) = max_step(
        p0,
        &dp,
        &m.x,
        &dx,
        &m.facets,
        &m.candidates,
        &CcdOptions::default(),
    );
    match at {
        Some((q, f)) => (alpha, q as i64, f as i64),
        None => (alpha, -1, -1),
    }
}

/// Two index arrays of the same length.
type IndexPair<'py> = (
    Bound<'py, numpy::PyArray1<i64>>,
    Bound<'py, numpy::PyArray1<i64>>,
);

#[pymethods]
impl PyContactMesh {
    /// A mesh boundary: `vertices` (nv×D, D = 2 or 3) and `facets` (m×D vertex indices: edges
    /// in 2D, triangles in 3D), femp's barrier of activation distance `dhat` and stiffness
    /// `kappa`, `hessian` `"projected"` or `"gauss_newton"`.
    #[new]
    #[pyo3(signature = (vertices, facets, dhat, kappa, hessian = "projected"))]
    fn new(
        vertices: PyReadonlyArray2<'_, f64>,
        facets: PyReadonlyArray2<'_, i64>,
        dhat: f64,
        kappa: f64,
        hessian: &str,
    ) -> PyResult<Self> {
        let barrier = LogBarrier::new(dhat, kappa).map_err(err)?;
        let hessian = match hessian {
            "projected" => BarrierHessian::Projected,
            "gauss_newton" => BarrierHessian::GaussNewton,
            h => {
                return Err(err(format!(
                    "hessian = {h:?}: expected \"projected\" or \"gauss_newton\""
                )));
            }
        };
        let mesh = match vertices.as_array().ncols() {
            2 => AnyMesh::D2(Box::new(Mesh::new(
                rows::<2>(&vertices, "vertices")?,
                &facets,
                barrier,
                hessian,
            )?)),
            3 => AnyMesh::D3(Box::new(Mesh::new(
                rows::<3>(&vertices, "vertices")?,
                &facets,
                barrier,
                hessian,
            )?)),
            c => return Err(err(format!("vertices: {c} columns, expected 2 or 3"))),
        };
        Ok(Self { mesh })
    }

    /// Move the mesh's vertices (nv×D).
    fn set_vertices(&mut self, vertices: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        with_mesh!(&mut self.mesh, m => {
            let x = rows(&vertices, "vertices")?;
            if x.len() != m.x.len() {
                return Err(err(format!("vertices: {} rows, the mesh has {}", x.len(), m.x.len())));
            }
            m.x = x;
            Ok(())
        })
    }

    /// Broad phase: the (point, facet) pairs whose boxes come within `within` (default d̂).
    #[pyo3(signature = (points, within = None))]
    fn candidates<'py>(
        &mut self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
        within: Option<f64>,
    ) -> PyResult<IndexPair<'py>> {
        let (p, f) = with_mesh!(&mut self.mesh, m => {
            let pts = rows(&points, "points")?;
            let d = within.unwrap_or(m.potential.barrier.dhat);
            if !(d >= 0.0 && d.is_finite()) {
                return Err(err(format!("within = {d}: must be ≥ 0")));
            }
            py.detach(|| {
                candidates_within(&pts, &m.x, &m.facets, d, &mut m.candidates);
                let (mut p, mut f) = (Vec::new(), Vec::new());
                for q in 0..pts.len() {
                    for &g in m.candidates.of(q) {
                        p.push(q as i64);
                        f.push(i64::from(g));
                    }
                }
                (p, f)
            })
        });
        Ok((
            Array1::from(p).into_pyarray(py),
            Array1::from(f).into_pyarray(py),
        ))
    }

    /// The barrier potential `Σ ω b(d)` of `points` (weights ω, default 1) against the facets,
    /// with duplicate features counted once (BFEMP eqs. 31–32): `(value, terms, gradient,
    /// (rows, cols, values))`, the gradient over the points then the mesh's vertices
    /// ((n + nv)×D), the Hessian (PSD, as Newton uses it) as COO triplets over the same
    /// numbering × D (duplicates to be summed); with `hessian=False`, empty triplets.
    #[pyo3(signature = (points, weights = None, hessian = true))]
    #[allow(clippy::type_complexity)]
    fn potential<'py>(
        &mut self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
        weights: Option<PyReadonlyArray1<'py, f64>>,
        hessian: bool,
    ) -> PyResult<(
        f64,
        usize,
        Bound<'py, numpy::PyArray2<f64>>,
        Bound<'py, PyDict>,
    )> {
        let d = self.dimension();
        let (value, n, grad, unknowns, rows_, cols, vals) = with_mesh!(&mut self.mesh, m => {
            let pts = rows(&points, "points")?;
            let w = point_weights(weights.as_ref(), pts.len())?;
            let r = py.detach(|| potential_d(m, &pts, &w, hessian))?;
            (r.0, r.1, r.2, m.x.len() + pts.len(), r.3, r.4, r.5)
        });
        let g = Array2::from_shape_vec((unknowns, d), grad).map_err(err)?;
        let h = PyDict::new(py);
        h.set_item("rows", Array1::from(rows_).into_pyarray(py))?;
        h.set_item("cols", Array1::from(cols).into_pyarray(py))?;
        h.set_item("values", Array1::from(vals).into_pyarray(py))?;
        Ok((value, n, g.into_pyarray(py), h))
    }

    /// The active terms (distance below d̂) of `points`: a dict of `point`, `kind` (1 vertex,
    /// 2 edge, 3 face: the closest feature), `feature` (its mesh vertices, −1 padded, ×3),
    /// `distance` and `weight` (ω times the feature's duplicate-removal coefficient).
    #[pyo3(signature = (points, weights = None))]
    fn active<'py>(
        &mut self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
        weights: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let a = with_mesh!(&mut self.mesh, m => {
            let pts = rows(&points, "points")?;
            let w = point_weights(weights.as_ref(), pts.len())?;
            py.detach(|| active_d(m, &pts, &w))?
        });
        let d = PyDict::new(py);
        let n = a.0.len();
        d.set_item("point", Array1::from(a.0).into_pyarray(py))?;
        d.set_item("kind", Array1::from(a.1).into_pyarray(py))?;
        let f = Array2::from_shape_fn((n, 3), |(i, k)| a.2[i][k]);
        d.set_item("feature", f.into_pyarray(py))?;
        d.set_item("distance", Array1::from(a.3).into_pyarray(py))?;
        d.set_item("weight", Array1::from(a.4).into_pyarray(py))?;
        Ok(d)
    }

    /// Batched CCD: the largest `α ∈ (0, 1]` such that no point reaches a facet along the
    /// linear motion `points0 → points1` while the mesh moves from its vertices to `vertices1`
    /// (default: it stays), conservative (additive CCD); with the limiting `(point, facet)`,
    /// `(-1, -1)` when nothing limits it.
    #[pyo3(signature = (points0, points1, vertices1 = None))]
    fn max_step(
        &mut self,
        py: Python<'_>,
        points0: PyReadonlyArray2<'_, f64>,
        points1: PyReadonlyArray2<'_, f64>,
        vertices1: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<(f64, i64, i64)> {
        with_mesh!(&mut self.mesh, m => {
            let p0 = rows(&points0, "points0")?;
            let p1 = rows(&points1, "points1")?;
            if p0.len() != p1.len() {
                return Err(err(format!("points0 and points1: {} and {} rows", p0.len(), p1.len())));
            }
            let x1 = vertices1.as_ref().map(|v| rows(v, "vertices1")).transpose()?;
            if let Some(x1) = &x1 && x1.len() != m.x.len() {
                return Err(err(format!("vertices1: {} rows, the mesh has {}", x1.len(), m.x.len())));
            }
            Ok(py.detach(|| max_step_d(m, &p0, &p1, x1)))
        })
    }

    /// Number of mesh vertices.
    #[getter]
    fn num_vertices(&self) -> usize {
        with_mesh!(&self.mesh, m => m.x.len())
    }

    /// 2 or 3.
    #[getter]
    fn dimension(&self) -> usize {
        match self.mesh {
            AnyMesh::D2(_) => 2,
            AnyMesh::D3(_) => 3,
        }
    }
}
