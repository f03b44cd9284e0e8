//! The contact pairs of a scene: which points (an MPM body's particles, a FEM body's boundary
//! vertices) may touch which FEM body's boundary, with each pair's barrier and friction (the
//! scene's contact settings, overridden per pair).

use femp_contact::friction::FrictionParams;
use femp_contact::{BarrierHessian, BoundaryTopology, ContactPotential, LogBarrier};
use nalgebra::SVector;

use crate::bodies::{FemBody, Mpm, Pair, Points};
use crate::error::{SimError, invalid};
use crate::scene::{BarrierHessianSpec, BodySpec, SceneSpec};

/// The pairs of `spec`'s bodies that may touch, every FEM body against every other body but
/// two fully prescribed ones, MPM bodies against FEM bodies (MPM–MPM contact goes through the
/// shared grid). `slot` gives each scene body's kind and index (`(true, k)`: MPM body `k` of
/// `mpm`; `(false, k)`: `fem[k]`). Refuses a d̂ not smaller than the smaller body of a pair.
pub(crate) fn contact_pairs<const D: usize>(
    spec: &SceneSpec,
    slot: &[(bool, usize)],
    mpm: Option<&Mpm<D>>,
    fem: &[FemBody<D>],
) -> Result<Vec<Pair<D>>, SimError> {
    let mut pairs = Vec::new();
    if let Some(c) = &spec.contact {
        let names: Vec<&str> = spec.bodies.iter().map(BodySpec::name).collect();
        for i in 0..names.len() {
            for j in i + 1..names.len() {
                let (si, sj) = (slot[i], slot[j]);
                if si.0 && sj.0 {
                    continue; // MPM–MPM: through the shared grid.
                }
                let over = c.pairs.iter().find(|p| {
                    (p.bodies[0] == names[i] && p.bodies[1] == names[j])
                        || (p.bodies[0] == names[j] && p.bodies[1] == names[i])
                });
                if over.is_some_and(|p| !p.enabled) {
                    continue;
                }
                let dhat = over.and_then(|p| p.dhat).unwrap_or(c.dhat);
                // A barrier reaching across a whole body is no contact gap: every point
                // would be a candidate of every facet (one Newton iteration of a 1 m cube
                // with d̂ = 10 m took minutes). Refuse d̂ not below the smaller body's size.
                let extent = |(is_mpm, k): (bool, usize)| -> f64 {
                    let pts: &[SVector<f64, D>] = if is_mpm {
                        match mpm {
                            Some(m) => &m.x[m.bodies[k].range.0..m.bodies[k].range.1],
                            None => &[],
                        }
                    } else {
                        &fem[k].x
                    };
                    crate::overlap::bounding_box(pts)
                        .map_or(f64::INFINITY, |(lo, hi)| (hi - lo).max())
                };
                let (ei, ej) = (extent(si), extent(sj));
                let (size, small) = if ei <= ej {
                    (ei, names[i])
                } else {
                    (ej, names[j])
                };
                if size > 0.0 && dhat >= size {
                    let field =
                        match c.pairs.iter().position(|p| {
                            p.dhat.is_some() && over.is_some_and(|o| std::ptr::eq(o, p))
                        }) {
                            Some(k) => format!("contact.pairs[{k}].dhat"),
                            None => "contact.dhat".to_string(),
                        };
                    return Err(invalid(
                        field,
                        format!(
                            "d̂ = {dhat} m between `{}` and `{}` is not smaller than `{small}` ({size:.3e} m across): the barrier would act between points farther apart than the body is large; d̂ is a small gap (the papers use about 1e-3 of a body's size)",
                            names[i], names[j]
                        ),
                    ));
                }
                let kappa = over.and_then(|p| p.kappa).unwrap_or(c.kappa);
                let mu = over.and_then(|p| p.friction).unwrap_or(c.friction);
                let eps_v = over.and_then(|p| p.eps_v).unwrap_or(c.eps_v);
                let barrier =
                    LogBarrier::new(dhat, kappa).map_err(|e| invalid("contact", e.to_string()))?;
                let friction = FrictionParams::new(mu, eps_v, spec.time.dt)
                    .map_err(|e| invalid("contact", e.to_string()))?;
                let mut add = |points: Points,
                               facets_of: usize,
                               names: (String, String)|
                 -> Result<(), SimError> {
                    let body = &fem[facets_of];
                    let topo = BoundaryTopology::<D>::new(&body.facets, body.mesh.num_vertices())
                        .map_err(|e| {
                        invalid(format!("bodies `{}`", body.name), e.to_string())
                    })?;
                    pairs.push(Pair {
                        names,
                        points,
                        facets_of,
                        potential: ContactPotential::new(barrier, topo).with_hessian(
                            match c.hessian {
                                BarrierHessianSpec::GaussNewton => BarrierHessian::GaussNewton,
                                BarrierHessianSpec::Projected => BarrierHessian::Projected,
                            },
                        ),
                        friction,
                    });
                    Ok(())
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
                    // MPM–MPM: skipped above (through the shared grid).
                    ((true, _), (true, _)) => {}
                }
            }
        }
    }
    Ok(pairs)
}
