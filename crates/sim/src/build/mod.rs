//! Building bodies from scene specs: particle sampling of MPM shapes, transforms, materials and
//! rigid initial velocities here; an MPM body's particles in `mpm`, a FEM body in `fem`, the
//! contact pairs in `pairs`.

pub(crate) mod fem;
pub(crate) mod mpm;
pub(crate) mod pairs;

use std::path::Path;

use femp_fem::Mesh;
use femp_fem::mesh::gmsh;
use nalgebra::{SMatrix, SVector, Vector3};

use crate::error::SimError;
use crate::motion::rotation;
use crate::scene::{Sampling, ShapeSpec, TransformSpec};

/// `v + ω × (x − c)` (2D: ω about z).
pub(crate) fn rigid_velocity<const D: usize>(
    v: &SVector<f64, D>,
    w: &[f64],
    x: &SVector<f64, D>,
    c: &SVector<f64, D>,
) -> SVector<f64, D> {
    let r = x - c;
    let mut out = *v;
    if D == 2 {
        out[0] -= w[0] * r[1];
        out[1] += w[0] * r[0];
    } else {
        out[0] += w[1] * r[D - 1] - w[2] * r[1];
        out[1] += w[2] * r[0] - w[0] * r[D - 1];
        out[D - 1] += w[0] * r[1] - w[1] * r[0];
    }
    out
}

/// Particles sampled in a shape: positions and volumes.
#[derive(Clone, Debug, Default)]
pub struct Samples<const D: usize> {
    /// Positions.
    pub x: Vec<SVector<f64, D>>,
    /// Volumes (area in 2D).
    pub volume: Vec<f64>,
}

fn v<const D: usize>(a: &[f64]) -> SVector<f64, D> {
    SVector::from_column_slice(a)
}

/// The rigid map of a transform spec.
pub fn transform_fn<const D: usize>(
    t: &TransformSpec,
) -> impl Fn(&SVector<f64, D>) -> SVector<f64, D> + use<D> {
    let about = t.about.as_deref().map_or_else(SVector::zeros, v::<D>);
    let trans = t.translate.as_deref().map_or_else(SVector::zeros, v::<D>);
    let angle = t.rotate_deg.to_radians();
    let r: SMatrix<f64, D, D> = if D == 2 {
        rotation::<D>(&[angle], 1.0)
    } else {
        let axis = t.axis.clone().unwrap_or_else(|| vec![0.0, 0.0, 1.0]);
        let n = Vector3::new(axis[0], axis[1], axis[2]).normalize() * angle;
        rotation::<D>(&[n.x, n.y, n.z], 1.0)
    };
    move |x: &SVector<f64, D>| r * (x - about) + about + trans
}

/// Sample an MPM shape with `per_axis^D` particles per cell of size `h`.
pub fn sample_shape<const D: usize>(
    shape: &ShapeSpec,
    h: f64,
    per_axis: usize,
    base_dir: &Path,
    field: &str,
) -> Result<Samples<D>, SimError> {
    let s = h / per_axis as f64;
    let mut out = Samples::default();
    match shape {
        ShapeSpec::Box {
            min,
            max,
            transform,
        } => {
            // A lattice aligned with the box (so faces are flat rows of particles), filling it
            // exactly; then the placement.
            let (lo, hi) = (v::<D>(min), v::<D>(max));
            let n: [usize; D] =
                std::array::from_fn(|a| (((hi[a] - lo[a]) / s).round() as usize).max(1));
            let step: SVector<f64, D> = SVector::from_fn(|a, _| (hi[a] - lo[a]) / n[a] as f64);
            let vol: f64 = (0..D).map(|a| step[a]).product();
            let tf = transform.as_ref().map(transform_fn::<D>);
            let total: usize = n.iter().product();
            for flat in 0..total {
                let mut rem = flat;
                let mut p = SVector::<f64, D>::zeros();
                for a in 0..D {
                    let i = rem % n[a];
                    rem /= n[a];
                    p[a] = lo[a] + (i as f64 + 0.5) * step[a];
                }
                out.x.push(tf.as_ref().map_or(p, |f| f(&p)));
                out.volume.push(vol);
            }
        }
        ShapeSpec::Disk {
            center,
            radius,
            sampling,
        } => {
            let c = v::<D>(center);
            let r = *radius;
            if *sampling == Sampling::Polar {
                polar(&mut out, c, 0.0, r, s);
            } else {
                lattice(&mut out, c.add_scalar(-r), c.add_scalar(r), s, |p| {
                    (p - c).norm() <= r
                });
            }
        }
        ShapeSpec::Ring {
            center,
            r_in,
            r_out,
            sampling,
        } => {
            let c = v::<D>(center);
            let (a, b) = (*r_in, *r_out);
            if *sampling == Sampling::Polar {
                polar(&mut out, c, a, b, s);
            } else {
                lattice(&mut out, c.add_scalar(-b), c.add_scalar(b), s, |p| {
                    let d = (p - c).norm();
                    d >= a && d <= b
                });
            }
        }
        ShapeSpec::SemicircularRing {
            center,
            r_in,
            r_out,
        } => {
            let c = v::<D>(center);
            let (a, b) = (*r_in, *r_out);
            lattice(&mut out, c.add_scalar(-b), c.add_scalar(b), s, |p| {
                let d = (p - c).norm();
                d >= a && d <= b && p[1] >= c[1]
            });
        }
        ShapeSpec::Mesh(never) => match *never {},
        ShapeSpec::File(f) => {
            let mesh: Mesh<D> = gmsh::read_msh_with(
                &base_dir.join(&f.path),
                gmsh::ReadOptions {
                    reorient: f.reorient,
                },
            )
            .map_err(|e| SimError::Build {
                context: format!("{field}.file.path"),
                message: e.to_string(),
            })?;
            let (lo, hi) = mesh.bounding_box();
            let thinnest = (hi - lo).min();
            if thinnest < h {
                return Err(SimError::Invalid {
                    field: "mpm.grid_spacing".into(),
                    message: format!(
                        "{h} is coarser than the mesh of {field}.file.path is thick ({thinnest}): the \
                         grid must resolve every MPM body with at least one cell across"
                    ),
                });
            }
            let cells = mesh.cells().to_vec();
            let xs = mesh.vertices().to_vec();
            lattice(&mut out, lo, hi, s, |p| {
                cells.iter().any(|c| inside_simplex(p, &c[..D + 1], &xs))
            });
        }
    }
    if out.x.is_empty() {
        return Err(SimError::Invalid {
            field: field.to_string(),
            message: format!(
                "the shape contains no particle at grid spacing {h} and {per_axis} particles per cell axis"
            ),
        });
    }
    Ok(out)
}

/// 2D: concentric circles between radii `r0` and `r1` about `c`, `n = round((r1 − r0)/s)` rings
/// at the mid-radii, each with `round(2πr/Δr)` equally spaced particles sharing its area; the
/// areas add up to the annulus exactly.
fn polar<const D: usize>(out: &mut Samples<D>, c: SVector<f64, D>, r0: f64, r1: f64, s: f64) {
    let n = (((r1 - r0) / s).round() as usize).max(1);
    let dr = (r1 - r0) / n as f64;
    for j in 0..n {
        let r = r0 + (j as f64 + 0.5) * dr;
        let count = ((std::f64::consts::TAU * r / dr).round() as usize).max(1);
        let area = std::f64::consts::TAU * r * dr / count as f64;
        // Alternate rings are offset by half a spacing.
        let phase = if j % 2 == 0 { 0.0 } else { 0.5 };
        for k in 0..count {
            let t = std::f64::consts::TAU * (k as f64 + phase) / count as f64;
            let mut p = c;
            p[0] += r * t.sin();
            p[1] -= r * t.cos();
            out.x.push(p);
            out.volume.push(area);
        }
    }
}

/// Points `(i + ½) s` inside `[lo, hi]` for which `inside` holds, each with volume `s^D`.
fn lattice<const D: usize>(
    out: &mut Samples<D>,
    lo: SVector<f64, D>,
    hi: SVector<f64, D>,
    s: f64,
    inside: impl Fn(&SVector<f64, D>) -> bool,
) {
    let i0: [i64; D] = std::array::from_fn(|a| (lo[a] / s - 0.5).floor() as i64);
    let i1: [i64; D] = std::array::from_fn(|a| (hi[a] / s - 0.5).ceil() as i64);
    let n: [usize; D] = std::array::from_fn(|a| (i1[a] - i0[a] + 1).max(0) as usize);
    let total: usize = n.iter().product();
    let vol = s.powi(D as i32);
    for flat in 0..total {
        let mut rem = flat;
        let mut p = SVector::<f64, D>::zeros();
        for a in 0..D {
            let i = i0[a] + (rem % n[a]) as i64;
            rem /= n[a];
            p[a] = (i as f64 + 0.5) * s;
        }
        if inside(&p) {
            out.x.push(p);
            out.volume.push(vol);
        }
    }
}

/// Whether `p` lies in the closed simplex with vertex indices `c`.
pub fn inside_simplex<const D: usize>(
    p: &SVector<f64, D>,
    c: &[usize],
    x: &[SVector<f64, D>],
) -> bool {
    let t = SMatrix::<f64, D, D>::from_fn(|r, k| x[c[k + 1]][r] - x[c[0]][r]);
    let Some(inv) = femp_fem::linalg::inverse(&t) else {
        return false;
    };
    let b = inv * (p - x[c[0]]);
    let tol = -1e-12;
    b.iter().all(|&l| l >= tol) && b.sum() <= 1.0 - tol
}
