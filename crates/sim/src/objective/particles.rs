//! MPM elasticity `w Σ_q V_q Ψ(F_q)`, its gradient and Hessian on the grid by the chain rule
//! (`F_q = (I + Σ_i u_i ∇w_iqᵀ) F_qⁿ`), and the particles' det F > 0 step bound.

use femp_fem::inversion::first_det_root;
use femp_fem::{Hyperelastic, Tangent, chain_hessian_add_upper};
use femp_kernels::transfer;
use femp_solver::Triplets;
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use super::config::{Configuration, Dofs, block};
use crate::bodies::Mpm;

/// `w ∂/∂x_i Σ_q V_q Ψ(F_q)` for every grid node `i` of the current stencils (parallel) into
/// `out`, with `fq` the particles' deformation gradients at the configuration.
fn node_forces<const D: usize>(
    m: &Mpm<D>,
    fq: &[SMatrix<f64, D, D>],
    w: f64,
    n_grid: usize,
    out: &mut Vec<SVector<f64, D>>,
) {
    let st = &m.stencils;
    out.clear();
    out.resize(n_grid, SVector::zeros());
    st.par_scatter_rows(out, 1, |particles, rows| {
        for &p in particles {
            let p = p as usize;
            let pk = m.bodies[m.body[p] as usize].material.first_piola(&fq[p]) * (w * m.volume[p]);
            let ft = m.f[p].transpose();
            st.particle(p).for_each(|i, _, grad| {
                rows.row(i)[0] += pk * (ft * grad);
            });
        }
    });
}

/// The elastic energy's gradient on the grid at the start of a step (every grid node at its
/// rest position, so `F_q = F_qⁿ`) into `out`: MPM's internal forces `−out` there, from which
/// Newmark's start-of-step acceleration is evaluated on this step's grid rather than carried
/// through the particles.
pub(crate) fn start_gradient<const D: usize>(m: &Mpm<D>, out: &mut Vec<SVector<f64, D>>) {
    node_forces(m, &m.f, 1.0, m.stencils.num_nodes(), out);
}

/// The particles' elastic energy and its derivatives, with the buffers they reuse.
pub(super) struct ParticleElasticity<'a, const D: usize> {
    pub mpm: Option<&'a Mpm<D>>,
    /// The grid Hessian of the last Hessian: the particles' blocks, and the contact terms'
    /// blocks between grid nodes (scattered by the contact term).
    pub gh: GridHessian<D>,
    /// Node forces of the last gradient.
    node_force: Vec<SVector<f64, D>>,
    /// Entries per task of [`GridHessian::emit`].
    emit_counts: Vec<usize>,
}

impl<'a, const D: usize> ParticleElasticity<'a, D> {
    pub fn new(mpm: Option<&'a Mpm<D>>) -> Self {
        Self {
            mpm,
            gh: GridHessian::new(),
            node_force: Vec::new(),
            emit_counts: Vec::new(),
        }
    }

    /// `Σ_q V_q Ψ(F_q)` (not yet times `w`).
    pub fn energy(&self, cfg: &Configuration<D>) -> f64 {
        let fq = &cfg.fq;
        self.mpm.map_or(0.0, |m| {
            // Fixed chunks summed in order: the same bits on any number of threads.
            const CHUNK: usize = 1024;
            let n = m.x.len();
            (0..n.div_ceil(CHUNK))
                .into_par_iter()
                .map(|c| {
                    (c * CHUNK..((c + 1) * CHUNK).min(n))
                        .map(|p| {
                            m.volume[p]
                                * m.bodies[m.body[p] as usize].material.energy_density(&fq[p])
                        })
                        .sum::<f64>()
                })
                .collect::<Vec<f64>>()
                .into_iter()
                .sum::<f64>()
        })
    }

    /// Add the gradient (node forces `w Σ_p V_p P(F_p) F_pⁿᵀ ∇w_ip`, particle groups in
    /// parallel) into `g`.
    pub fn add_gradient(&mut self, cfg: &Configuration<D>, dofs: &Dofs, w: f64, g: &mut [f64]) {
        let Some(m) = self.mpm else {
            return;
        };
        node_forces(m, &cfg.fq, w, dofs.n_grid, &mut self.node_force);
        for (i, f) in self.node_force.iter().enumerate() {
            for a in 0..D {
                g[i * D + a] += f[a];
            }
        }
    }

    /// The particles' Hessian blocks into the grid Hessian (cleared first).
    pub fn hessian(&mut self, cfg: &Configuration<D>, dofs: &Dofs, w: f64, exact: bool) {
        if let Some(m) = self.mpm {
            particle_hessians(m, &cfg.fq, dofs.n_grid, w, exact, &mut self.gh);
        }
    }

    /// Clear the grid Hessian without adding the particles' blocks (objectives without
    /// elasticity; contact terms between particles still scatter into it).
    pub fn clear_hessian(&mut self, dofs: &Dofs) {
        if let Some(m) = self.mpm {
            let st = &m.stencils;
            self.gh.reset(
                dofs.n_grid,
                st.stencil_axes(),
                st.grid().kernel().nodes_per_axis(),
            );
        }
    }

    /// Append the grid Hessian's triplets to `h`.
    pub fn emit(&mut self, h: &mut Triplets) {
        if self.mpm.is_some() {
            self.gh.emit(h, &mut self.emit_counts);
        }
    }

    /// The particles' motion `dq` along the grid increments `pg` of direction `p`; `false` if it
    /// cannot be interpolated (a non-finite direction).
    pub fn motion(
        &self,
        p: &[f64],
        dofs: &Dofs,
        pg: &mut Vec<SVector<f64, D>>,
        dq: &mut Vec<SVector<f64, D>>,
    ) -> bool {
        pg.clear();
        dq.clear();
        let Some(m) = self.mpm else {
            return true;
        };
        pg.extend((0..dofs.n_grid).map(|i| block(p, i)));
        dq.resize(m.x.len(), SVector::zeros());
        transfer::interpolate(&m.stencils, pg, dq).is_ok()
    }

    /// The largest increment grid increments `p` (D per node) make at a particle: of its
    /// position and, times the grid spacing h, of its deformation gradient — bounded by
    /// `Σ_i (w_iq + h‖∇w_iq‖) ‖p_i‖_∞` over its stencil, which also bounds the change of its
    /// APIC affine velocity. A node a particle touches with weight w moves it by w of its own
    /// increment (and its F by about √w), so nodes nearly without mass do not hold the test up.
    pub fn increment_size(&self, p: &[f64]) -> f64 {
        let Some(m) = self.mpm else {
            return 0.0;
        };
        let st = &m.stencils;
        let h = st.grid().h();
        (0..m.x.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|q| {
                let mut s = 0.0;
                st.particle(q).for_each(|i, w, grad| {
                    let pi = p[i * D..i * D + D]
                        .iter()
                        .fold(0.0f64, |a, v| a.max(v.abs()));
                    s += (w + h * grad.norm()) * pi;
                });
                s
            })
            .reduce(|| 0.0, f64::max)
    }

    /// The largest step fraction (≤ 1) along grid increments `pg` before a particle's det F
    /// reaches zero.
    pub fn det_bound(&self, cfg: &Configuration<D>, pg: &[SVector<f64, D>]) -> f64 {
        let Some(m) = self.mpm else {
            return 1.0;
        };
        let st = &m.stencils;
        let gu = &cfg.gu;
        (0..m.x.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|q| {
                let mut g1 = SMatrix::<f64, D, D>::zeros();
                st.particle(q).for_each(|i, _, grad| {
                    g1 += pg[i] * grad.transpose();
                });
                first_det_root(&gu[q], &g1).unwrap_or(1.0)
            })
            .reduce(|| 1.0, f64::min)
    }
}

/// One slot of a grid node's Hessian row: the block coupling it to one neighbour.
#[derive(Clone, Copy)]
pub(super) struct HBlock<const D: usize> {
    pub m: SMatrix<f64, D, D>,
    pub nbr: u32,
}

/// Grid-node Hessian blocks stored by node and neighbour offset (`δ ∈ [−2, 2]^D` for the
/// 3-node kernel): every particle's stencil couples only such pairs, so a particle's `N^D × N^D`
/// blocks land in fixed slots (a table from the stencil's per-axis offsets, no look-up), and
/// particle groups fill their nodes' rows in parallel without races
/// ([`Stencils::par_scatter_rows`](femp_kernels::Stencils::par_scatter_rows)).
pub(super) struct GridHessian<const D: usize> {
    pub(super) slots: usize,
    pub(super) rows: Vec<HBlock<D>>,
    /// `pair_slot[a·N^D + b]`: the slot of stencil entry `b` in the row of entry `a`.
    pub(super) pair_slot: Vec<u16>,
}

impl<const D: usize> GridHessian<D> {
    pub(super) fn new() -> Self {
        Self {
            slots: 0,
            rows: Vec::new(),
            pair_slot: Vec::new(),
        }
    }

    /// Clear for `n` nodes with stencils whose per-axis offsets are `axes` (`0..npa`).
    fn reset(&mut self, n: usize, axes: &[[u8; D]], npa: usize) {
        let span = 2 * npa - 1;
        self.slots = span.pow(D as u32);
        let nn = axes.len();
        self.pair_slot.clear();
        for a in 0..nn {
            for b in 0..nn {
                let mut e = 0usize;
                for k in (0..D).rev() {
                    e = e * span + (axes[b][k] as usize + npa - 1 - axes[a][k] as usize);
                }
                self.pair_slot.push(e as u16);
            }
        }
        self.rows.clear();
        self.rows.resize(
            n * self.slots,
            HBlock {
                m: SMatrix::zeros(),
                nbr: u32::MAX,
            },
        );
    }

    /// Append the stored blocks' upper triangle to `h` as triplets, node by node and slot by slot
    /// (the order a sequential loop gives), nodes in parallel. The lower triangle is left out:
    /// the solver drops it (femp-solver's `Objective::hessian` contract), and it was half of
    /// the grid's triplets to write, compare and skip in every Hessian build.
    pub(super) fn emit(&self, h: &mut Triplets, counts: &mut Vec<usize>) {
        const NODES_PER_TASK: usize = 64;
        let slots = self.slots;
        let n_nodes = self.rows.len().checked_div(slots).unwrap_or(0);
        // Entries per task of consecutive nodes (`upper_columns` row by row).
        counts.clear();
        let node_entries = |i: usize| -> usize {
            self.rows[i * slots..(i + 1) * slots]
                .iter()
                .flat_map(|b| (0..D).map(move |rr| upper_columns(i, b, rr).len()))
                .sum()
        };
        counts.extend((0..n_nodes).step_by(NODES_PER_TASK).map(|first| {
            (first..(first + NODES_PER_TASK).min(n_nodes))
                .map(node_entries)
                .sum::<usize>()
        }));
        let total: usize = counts.iter().sum();
        h.append_with(total, |rows, cols, vals| {
            let mut parts = Vec::with_capacity(counts.len());
            let (mut r, mut c, mut v) = (rows, cols, vals);
            for (task, &len) in counts.iter().enumerate() {
                let (r0, r1) = r.split_at_mut(len);
                let (c0, c1) = c.split_at_mut(len);
                let (v0, v1) = v.split_at_mut(len);
                parts.push((task, r0, c0, v0));
                (r, c, v) = (r1, c1, v1);
            }
            parts.into_par_iter().for_each(|(task, r, c, v)| {
                let first = task * NODES_PER_TASK;
                let last = (first + NODES_PER_TASK).min(n_nodes);
                let mut k = 0;
                for i in first..last {
                    for b in &self.rows[i * slots..(i + 1) * slots] {
                        for rr in 0..D {
                            for cc in upper_columns(i, b, rr) {
                                r[k] = (i * D + rr) as u32;
                                c[k] = (b.nbr as usize * D + cc) as u32;
                                v[k] = b.m[(rr, cc)];
                                k += 1;
                            }
                        }
                    }
                }
            });
        });
    }
}

/// The columns of row `rr` of node `i`'s block `b` that lie in the Hessian's upper triangle
/// (the solver ignores entries below the diagonal): all of a block to a later node, those on
/// and above the diagonal of the node's own block, none of a block to an earlier node or of an
/// empty slot.
fn upper_columns<const D: usize>(i: usize, b: &HBlock<D>, rr: usize) -> std::ops::Range<usize> {
    match b.nbr as usize {
        _ if b.nbr == u32::MAX => 0..0,
        n if n < i => 0..0,
        n if n == i => rr..D,
        _ => 0..D,
    }
}

/// The particles' Hessian blocks `V_p Gᵀ A_p G` (`A_p` the tangent, PSD-projected unless
/// `exact`) into the grid Hessian, particle groups in parallel, each block added into its fixed
/// slot.
fn particle_hessians<const D: usize>(
    m: &Mpm<D>,
    fq: &[SMatrix<f64, D, D>],
    n_grid: usize,
    w: f64,
    exact: bool,
    gh: &mut GridHessian<D>,
) {
    let st = &m.stencils;
    gh.reset(
        n_grid,
        st.stencil_axes(),
        st.grid().kernel().nodes_per_axis(),
    );
    // Particle Hessians V_p Gᵀ A_p G (A_p the tangent, PSD-projected unless `exact`),
    // particle groups in parallel, each block added into its fixed slot.
    let nn = st.stencil_len();
    let (slots, pair_slot) = (gh.slots, &gh.pair_slot);
    st.par_scatter_rows(&mut gh.rows, slots, |particles, rows| {
        // Per group (hundreds of particles), not per particle. Particles come sorted by
        // stencil base within a group, so the blocks of all particles sharing a stencil
        // (one cell, ~particles-per-cell of them) are summed here and scattered once.
        let mut gvec = vec![SVector::<f64, D>::zeros(); nn];
        let mut ids = vec![0usize; nn];
        let mut cell_ids = vec![usize::MAX; nn];
        let mut acc = vec![SMatrix::<f64, D, D>::zeros(); nn * nn];
        let mut flush = |cell_ids: &[usize], acc: &mut [SMatrix<f64, D, D>]| {
            for a in 0..nn {
                let row = rows.row(cell_ids[a]);
                for b in 0..nn {
                    let block = if a <= b {
                        acc[a * nn + b]
                    } else {
                        acc[b * nn + a].transpose()
                    };
                    let slot = &mut row[pair_slot[a * nn + b] as usize];
                    slot.m += block;
                    slot.nbr = cell_ids[b] as u32;
                }
            }
            acc.iter_mut().for_each(|b| *b = SMatrix::zeros());
        };
        for &p in particles {
            let p = p as usize;
            let material = &m.bodies[m.body[p] as usize].material;
            let t: Tangent<D> = if exact {
                material.tangent(&fq[p])
            } else {
                material.tangent_psd(&fq[p])
            };
            let ft = m.f[p].transpose();
            let mut k = 0;
            st.particle(p).for_each(|i, _, grad| {
                ids[k] = i;
                gvec[k] = ft * grad;
                k += 1;
            });
            // The stencil is determined by its first (base) node.
            if ids[0] != cell_ids[0] {
                if cell_ids[0] != usize::MAX {
                    flush(&cell_ids, &mut acc);
                }
                cell_ids.copy_from_slice(&ids);
            }
            chain_hessian_add_upper(&t, &gvec, w * m.volume[p], &mut acc);
        }
        if cell_ids[0] != usize::MAX {
            flush(&cell_ids, &mut acc);
        }
    });
}
