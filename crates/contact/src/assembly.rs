//! The terms' derivatives ([`crate::TermDerivatives`]) gathered over a whole system: the
//! gradient over the points then the boundary vertices, and the Hessian as coordinate triplets
//! (duplicates to be summed) — what a caller without its own sparse matrix needs, e.g. the
//! Python package's `ContactMesh`, which hands the triplets to scipy.

use rayon::prelude::*;

use crate::ContactError;
use crate::potential::TermDerivatives;

/// A sparse matrix as coordinate triplets, duplicates to be summed, 32-bit indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coo {
    /// Row of each entry.
    pub rows: Vec<i32>,
    /// Column of each entry.
    pub cols: Vec<i32>,
    /// The entries.
    pub values: Vec<f64>,
}

/// Add the terms' gradients into `grad` and, with `hessian`, write their Hessian blocks as
/// triplets into it (replacing what it held), over the unknowns `points` (the terms' particles,
/// `n_points` of them) then the boundary vertices, `D` per point: vertex `v` of a term is
/// unknown `n_points + v`. `grad` holds `D` entries per unknown; the Hessian's triplets are
/// written in parallel, each term at its own offset. An error if the unknowns' count times `D`
/// does not fit a 32-bit index.
pub fn assemble<const D: usize>(
    derivatives: &[TermDerivatives<D>],
    n_points: usize,
    grad: &mut [f64],
    hessian: Option<&mut Coo>,
) -> Result<(), ContactError> {
    let unknowns = grad.len() / D;
    if i32::try_from(grad.len()).is_err() {
        return Err(ContactError::LengthMismatch {
            what: "unknowns × D (the triplets' indices are 32-bit)",
            expected: i32::MAX as usize,
            got: grad.len(),
        });
    }
    let index = |t: &TermDerivatives<D>, k: usize| {
        if k == 0 {
            t.particle as usize
        } else {
            n_points + t.vertices[k - 1] as usize
        }
    };
    for t in derivatives {
        for i in 0..t.n {
            let u = index(t, i);
            if u >= unknowns {
                return Err(ContactError::LengthMismatch {
                    what: "gradient (unknowns × D)",
                    expected: (u + 1) * D,
                    got: grad.len(),
                });
            }
            for a in 0..D {
                grad[u * D + a] += t.grad[i][a];
            }
        }
    }
    let Some(coo) = hessian else {
        return Ok(());
    };
    let sizes: Vec<usize> = derivatives.iter().map(|t| t.n * t.n * D * D).collect();
    let total: usize = sizes.iter().sum();
    // Every entry is written below: a buffer of the right size is reused as it is, and a new one
    // is allocated zeroed (pages the fill touches first, not written twice).
    if coo.values.len() != total {
        *coo = Coo {
            rows: vec![0; total],
            cols: vec![0; total],
            values: vec![0.0; total],
        };
    }
    let mut parts = Vec::with_capacity(sizes.len());
    let (mut r, mut c, mut v) = (&mut coo.rows[..], &mut coo.cols[..], &mut coo.values[..]);
    for &len in &sizes {
        let (r0, r1) = std::mem::take(&mut r).split_at_mut(len);
        let (c0, c1) = std::mem::take(&mut c).split_at_mut(len);
        let (v0, v1) = std::mem::take(&mut v).split_at_mut(len);
        parts.push((r0, c0, v0));
        (r, c, v) = (r1, c1, v1);
    }
    derivatives
        .par_iter()
        .zip(parts)
        .with_min_len(1024)
        .for_each(|(t, (r, c, v))| {
            // Indices were checked against the gradient's length above.
            let base: [i32; 4] =
                std::array::from_fn(|k| if k < t.n { (index(t, k) * D) as i32 } else { 0 });
            let mut e = 0;
            for i in 0..t.n {
                for j in 0..t.n {
                    let h = &t.hess[i][j];
                    for a in 0..D {
                        for b in 0..D {
                            r[e] = base[i] + a as i32;
                            c[e] = base[j] + b as i32;
                            v[e] = h[(a, b)];
                            e += 1;
                        }
                    }
                }
            }
        });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::broad_phase::{Candidates, candidates_within};
    use crate::{BoundaryTopology, ContactPotential, LogBarrier};
    use nalgebra::Vector2;

    /// Two points above a 2D polyline: the triplets summed into a dense matrix are the terms'
    /// blocks placed by hand, the gradient the blocks' sum, and a short gradient is an error.
    #[test]
    fn triplets_place_every_block_where_its_points_are() {
        let x = vec![
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.0),
            Vector2::new(2.0, 0.1),
        ];
        let facets = [[0, 1, 0], [1, 2, 0]];
        let pot = ContactPotential::new(
            LogBarrier::new(0.1, 1.0).unwrap(),
            BoundaryTopology::<2>::new(&facets, 3).unwrap(),
        );
        let p = vec![Vector2::new(0.5, 0.05), Vector2::new(1.02, 0.04)];
        let (mut cands, mut terms, mut ders) = (Candidates::default(), Vec::new(), Vec::new());
        candidates_within(&p, &x, pot.topology.facets(), 0.1, &mut cands);
        pot.collect_terms(&p, &[1.0, 2.0], &x, &cands, &mut terms)
            .unwrap();
        pot.derivatives(&terms, &p, &x, &mut ders);
        assert!(
            ders.len() >= 2 && ders.iter().any(|t| t.n == 3),
            "{} terms",
            ders.len()
        );
        let n = (p.len() + x.len()) * 2;
        let mut grad = vec![0.0; n];
        let mut coo = Coo::default();
        assemble(&ders, p.len(), &mut grad, Some(&mut coo)).unwrap();
        let mut dense = vec![0.0; n * n];
        for ((r, c), v) in coo.rows.iter().zip(&coo.cols).zip(&coo.values) {
            dense[*r as usize * n + *c as usize] += v;
        }
        let (mut want_g, mut want_h) = (vec![0.0; n], vec![0.0; n * n]);
        for t in &ders {
            let at = |k: usize| {
                if k == 0 {
                    t.particle as usize
                } else {
                    2 + t.vertices[k - 1] as usize
                }
            };
            for i in 0..t.n {
                for a in 0..2 {
                    want_g[at(i) * 2 + a] += t.grad[i][a];
                    for j in 0..t.n {
                        for b in 0..2 {
                            want_h[(at(i) * 2 + a) * n + at(j) * 2 + b] += t.hess[i][j][(a, b)];
                        }
                    }
                }
            }
        }
        assert_eq!(grad, want_g);
        assert_eq!(dense, want_h);
        assert!(assemble(&ders, p.len(), &mut grad[..4], None).is_err());
    }
}
