//! The contact pairs of a scene: which points (an MPM body's particles, a FEM body's boundary
//! vertices) may touch which FEM body's boundary, with each pair's contact law (the parser's
//! [`PairLaw`]: the scene's contact settings, overridden per pair).

use femp_contact::{BoundaryTopology, ContactPotential};
use nalgebra::SVector;

use crate::bodies::{FemBody, Mpm, Pair, Points};
use crate::error::{SimError, invalid};
use crate::scene::resolved::PairLaw;

/// The pairs of the scene's bodies (named `names`) that may touch, from their laws `laws`: an
/// MPM body's particles against a FEM body's facets, and a FEM body's boundary vertices against
/// another's facets both ways unless both are fully prescribed. `slot` gives each scene body's
/// kind and index (`(true, k)`: MPM body `k` of `mpm`; `(false, k)`: `fem[k]`). Refuses a d̂
/// not smaller than the smaller body of a pair.
pub(crate) fn contact_pairs<const D: usize>(
    laws: &[PairLaw],
    names: &[&str],
    slot: &[(bool, usize)],
    mpm: Option<&Mpm<D>>,
    fem: &[FemBody<D>],
) -> Result<Vec<Pair<D>>, SimError> {
    // Each body's size: its bounding box's longest side (once per body, not per pair).
    let extents: Vec<f64> = slot
        .iter()
        .map(|&(is_mpm, k)| {
            let pts: &[SVector<f64, D>] = if is_mpm {
                match mpm {
                    Some(m) => &m.x[m.bodies[k].range.0..m.bodies[k].range.1],
                    None => &[],
                }
            } else {
                &fem[k].x
            };
            crate::overlap::bounding_box(pts).map_or(f64::INFINITY, |(lo, hi)| (hi - lo).max())
        })
        .collect();
    let mut pairs = Vec::new();
    for law in laws {
        let [i, j] = law.bodies;
        let (si, sj) = (slot[i], slot[j]);
        let dhat = law.barrier.dhat;
        // A barrier reaching across a whole body is no contact gap: every point would be a
        // candidate of every facet (one Newton iteration of a 1 m cube with d̂ = 10 m took
        // minutes). Refuse d̂ not below the smaller body's size.
        let (ei, ej) = (extents[i], extents[j]);
        let (size, small) = if ei <= ej {
            (ei, names[i])
        } else {
            (ej, names[j])
        };
        if size > 0.0 && dhat >= size {
            return Err(invalid(
                law.dhat_field.clone(),
                format!(
                    "d̂ = {dhat} m between `{}` and `{}` is not smaller than `{small}` ({size:.3e} m across): the barrier would act between points farther apart than the body is large; d̂ is a small gap (the papers use about 1e-3 of a body's size)",
                    names[i], names[j]
                ),
            ));
        }
        let mut add = |points: Points, facets_of: usize, names: (String, String)| {
            let body = &fem[facets_of];
            let topo = BoundaryTopology::<D>::new(&body.facets, body.mesh.num_vertices())
                .map_err(|e| invalid(format!("bodies `{}`", body.name), e.to_string()))?;
            pairs.push(Pair {
                names,
                points,
                facets_of,
                potential: ContactPotential::new(law.barrier, topo).with_hessian(law.hessian),
                friction: law.friction,
            });
            Ok::<(), SimError>(())
        };
        let (ni, nj) = (names[i].to_string(), names[j].to_string());
        match (si, sj) {
            ((true, a), (false, b)) => {
                let range = mpm.map(|m| m.bodies[a].range).unwrap_or((0, 0));
                add(Points::Mpm { range }, b, (ni, nj))?;
            }
            ((false, a), (true, b)) => {
                let range = mpm.map(|m| m.bodies[b].range).unwrap_or((0, 0));
                add(Points::Mpm { range }, a, (nj, ni))?;
            }
            ((false, a), (false, b)) => {
                if fem[a].fully_prescribed && fem[b].fully_prescribed {
                    continue;
                }
                add(Points::Fem { body: a }, b, (ni.clone(), nj.clone()))?;
                add(Points::Fem { body: b }, a, (nj, ni))?;
            }
            // MPM–MPM pairs have no law: they touch through the shared grid.
            ((true, _), (true, _)) => {}
        }
    }
    Ok(pairs)
}
