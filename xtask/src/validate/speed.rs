//! Speed of APIC augury contact against the search-based penalty baseline (the augury paper's
//! efficiency claim: "about an order of magnitude" faster than a search-based scheme in
//! serial, and "trivially thread scalable"), on [`femp_augury::speed::facing_plates`]: two thin
//! plates half a mesh size apart, every vertex a boundary vertex, 2D and 3D, 10³ … 10⁵ boundary
//! nodes (10⁶ in the full tier), on 1 and 2 threads.
//!
//! Both methods take the same explicit step (central differences, the same elastic forces);
//! only the contact differs. Each configuration is timed as the median of repeated steps from
//! one saved state (so every timed step is the same step), the two methods alternating, after
//! one untimed step each; the whole step and its contact part (augury: normals, the correction
//! with its stencils and transfers, the scatter; baseline: broad phase, nearest facet,
//! forces) are reported separately. Timings include whatever else ran on the machine: run it
//! alone (`cargo xtask validate --only augury_speed`) for numbers to quote.

use anyhow::{Result, bail};
use femp_augury::explicit::{ExplicitState, ExplicitSystem, StepTiming};
use femp_augury::speed::{PlatesContact, facing_plates, time_step};

use super::charts::{self, Chart, Corner, Series, Style};
use super::experiment::Experiment;
use super::{Check, Ctx, Outcome, Tier};

/// Goals of issue 43 at 10⁵ boundary nodes: penalty time / augury time.
const GOAL_STEP: f64 = 2.0;
const GOAL_CONTACT: f64 = 5.0;

/// Medians of one configuration's timed steps (s), and augury's contact part broken down.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Timed {
    step: f64,
    contact: f64,
    /// Augury only: stencils, transfers (both medians), transfers per step.
    stencils: f64,
    transfers: f64,
    transfer_count: usize,
}

/// One configuration's timings.
#[derive(Clone)]
pub(super) struct Row {
    dim: usize,
    threads: usize,
    nodes: usize,
    augury: Timed,
    penalty: Timed,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Time `reps` steps of each system from its saved state, alternating; returns the medians.
fn time_pair<const D: usize>(
    aug: (&mut ExplicitSystem<D>, &ExplicitState<D>),
    pen: (&mut ExplicitSystem<D>, &ExplicitState<D>),
    reps: usize,
) -> Result<(Timed, Timed)> {
    let (mut a, mut p) = (Vec::new(), Vec::new());
    let mut parts = Vec::new();
    for _ in 0..reps {
        a.push(time_step(aug.0, aug.1)?);
        let c = aug
            .0
            .contact
            .as_ref()
            .map(|c| c.timing())
            .unwrap_or_default();
        parts.push(c);
        p.push(time_step(pen.0, pen.1)?);
    }
    let med = |v: &[StepTiming], f: fn(&StepTiming) -> f64| {
        median(&mut v.iter().map(f).collect::<Vec<_>>())
    };
    let augury = Timed {
        step: med(&a, |t| t.step_s),
        contact: med(&a, |t| t.contact_s),
        stencils: median(&mut parts.iter().map(|c| c.stencils_s).collect::<Vec<_>>()),
        transfers: median(&mut parts.iter().map(|c| c.transfers_s).collect::<Vec<_>>()),
        transfer_count: parts.last().map_or(0, |c| c.transfers),
    };
    let penalty = Timed {
        step: med(&p, |t| t.step_s),
        contact: med(&p, |t| t.contact_s),
        ..Timed::default()
    };
    Ok((augury, penalty))
}

/// Both systems at one size, timed on each thread count; also checks that a timed step is the
/// same step every time (the state after it, bit for bit).
fn measure<const D: usize>(
    nodes: usize,
    threads: &[usize],
    budget_s: f64,
    min_reps: usize,
    rows: &mut Vec<Row>,
) -> Result<bool> {
    let (mut aug, nb) = facing_plates::<D>(nodes, PlatesContact::Augury)?;
    let (mut pen, _) = facing_plates::<D>(nodes, PlatesContact::Penalty)?;
    let (sa, sp) = (aug.state(), pen.state());
    let mut same = true;
    for &t in threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build()?;
        let (augury, penalty) = pool.install(|| -> Result<(Timed, Timed)> {
            // One untimed step each (caches, page faults, the pool's threads), which also
            // sizes the number of repetitions to the time budget.
            let first = time_step(&mut aug, &sa)?.step_s + time_step(&mut pen, &sp)?.step_s;
            let after: Vec<_> = aug.bodies.iter().map(|b| b.x.clone()).collect();
            let reps = ((budget_s / first.max(1e-9)) as usize).clamp(min_reps, 200);
            let r = time_pair((&mut aug, &sa), (&mut pen, &sp), reps)?;
            same &= aug.bodies.iter().zip(&after).all(|(b, x)| b.x == *x);
            Ok(r)
        })?;
        rows.push(Row {
            dim: D,
            threads: t,
            nodes: nb,
            augury,
            penalty,
        });
    }
    Ok(same)
}

fn ms(s: f64) -> String {
    let ms = s * 1e3;
    if ms < 1.0 {
        format!("{ms:.3} ms")
    } else if ms < 100.0 {
        format!("{ms:.2} ms")
    } else {
        format!("{ms:.0} ms")
    }
}

fn power_of_ten(n: usize) -> String {
    let e = (n as f64).log10().round() as i32;
    let sup = |c: char| match c {
        '0' => '⁰',
        '1' => '¹',
        '2' => '²',
        '3' => '³',
        '4' => '⁴',
        '5' => '⁵',
        '6' => '⁶',
        '7' => '⁷',
        '8' => '⁸',
        _ => '⁹',
    };
    format!("≈ 10{}", e.to_string().chars().map(sup).collect::<String>())
}

/// Augury §4's speed claim.
#[derive(Default)]
pub(super) struct Speed;

/// The tier's boundary-node counts, time budget per timing (s) and least repetitions.
fn budget(tier: Tier) -> (&'static [usize], f64, usize) {
    match tier {
        Tier::Quick => (&[1_000, 10_000, 100_000], 0.3, 5),
        Tier::Full => (&[1_000, 10_000, 100_000, 1_000_000], 1.0, 9),
    }
}

/// The thread counts timed.
const THREADS: [usize; 2] = [1, 2];

impl Experiment for Speed {
    /// Boundary nodes and dimension.
    type Case = (usize, usize);
    /// Whether every timed step was the same step, and the timings per thread count.
    type Measured = (bool, Vec<Row>);

    fn cases(&self, ctx: &Ctx) -> Result<Vec<(usize, usize)>> {
        let (sizes, _, _) = budget(ctx.tier);
        Ok(sizes.iter().flat_map(|&n| [(n, 2), (n, 3)]).collect())
    }

    fn measure(&self, ctx: &Ctx, &(n, dim): &(usize, usize)) -> Result<(bool, Vec<Row>)> {
        let (_, budget_s, min_reps) = budget(ctx.tier);
        let mut rows = Vec::new();
        let same = if dim == 2 {
            measure::<2>(n, &THREADS, budget_s, min_reps, &mut rows)?
        } else {
            measure::<3>(n, &THREADS, budget_s, min_reps, &mut rows)?
        };
        Ok((same, rows))
    }

    fn checks(&self, _: &Ctx, runs: &[Run], out: &mut Outcome) -> Result<()> {
        let rows = sorted_rows(runs)?;
        let same = runs.iter().all(|(_, (same, _))| *same);
        out.checks.push(Check::holds(
            "every timed step of a system is the same step (its end state, bit for bit)",
            if same { "yes" } else { "no" }.into(),
            "yes",
            "exact",
            same,
        ));
        for r in &rows {
            let label = format!(
                "{}D, {} thread{}, {} boundary nodes",
                r.dim,
                r.threads,
                if r.threads == 1 { "" } else { "s" },
                power_of_ten(r.nodes)
            );
            let at_goal = (r.nodes as f64).log10().round() as i32 == 5;
            let step = r.penalty.step / r.augury.step;
            let contact = r.penalty.contact / r.augury.contact;
            out.checks.push(Check::info(
                &format!("{label} ({}): whole step, penalty / augury", r.nodes),
                format!(
                    "{} / {} = {step:.2}×",
                    ms(r.penalty.step),
                    ms(r.augury.step)
                ),
                if at_goal {
                    format!("≥ {GOAL_STEP}× (issue 43); paper: ~10× in serial")
                } else {
                    "—".into()
                },
            ));
            out.checks.push(Check::info(
                &format!("{label}: contact part, penalty / augury"),
                format!(
                    "{} / {} = {contact:.2}× (augury: stencils {}, {} transfers {})",
                    ms(r.penalty.contact),
                    ms(r.augury.contact),
                    ms(r.augury.stencils),
                    r.augury.transfer_count,
                    ms(r.augury.transfers)
                ),
                if at_goal {
                    format!("≥ {GOAL_CONTACT}× (issue 43)")
                } else {
                    "—".into()
                },
            ));
        }
        // How far from the goals, and why: per-particle costs at 10⁵ nodes, 1 thread.
        for dim in [2usize, 3] {
            let Some(r) = rows.iter().find(|r| {
                r.dim == dim && r.threads == 1 && (r.nodes as f64).log10().round() == 5.0
            }) else {
                continue;
            };
            let per = |s: f64| s / r.nodes as f64 * 1e9;
            let rest = r.augury.contact - r.augury.stencils - r.augury.transfers;
            out.notes.push(format!(
                "{dim}D, 10⁵ boundary nodes, 1 thread: augury's whole step is {:.2}× the baseline's \
                 speed (goal {GOAL_STEP}×) and its contact part {:.2}× (goal {GOAL_CONTACT}×). Per \
                 boundary particle, augury's contact costs {:.0} ns: {:.0} ns per APIC transfer \
                 (particle-to-grid and back over the {}-node stencil, with the affine B term; {} per \
                 step), {:.0} ns for the stencils and {:.0} ns for normals, gathering and the \
                 iteration's per-particle work; the baseline's search and forces cost {:.0} ns per \
                 boundary vertex. For the contact goal at this size augury's contact would have to take \
                 {:.0} ns per particle.",
                r.penalty.step / r.augury.step,
                r.penalty.contact / r.augury.contact,
                per(r.augury.contact),
                per(r.augury.transfers) / r.augury.transfer_count.max(1) as f64,
                3usize.pow(dim as u32),
                r.augury.transfer_count,
                per(r.augury.stencils),
                per(rest),
                per(r.penalty.contact),
                per(r.penalty.contact) / GOAL_CONTACT,
            ));
        }
        out.notes.push(
            "The scene: two plates (2D: strips of n × 1 squares; 3D: k × 1 × k cubes, 6 tetrahedra \
             each), E = 1e6 Pa, half a mesh size apart, every vertex a boundary vertex, at rest, \
             Δt a quarter of the explicit stability estimate. Augury: APIC, one friction iteration \
             (μ = 0.3), grid spacing twice the mesh size, τ = Δt. Baseline: femp-contact's \
             uniform-grid broad phase for the facets within one mesh size of each boundary vertex, \
             the nearest one in plain double precision, a penalty force k = E per unit \
             penetration; the search runs in parallel, the forces are added in vertex order. \
             Medians of repeated steps from one saved state, the methods alternating."
                .into(),
        );
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[Run], out: &mut Outcome) -> Result<()> {
        let rows = sorted_rows(runs)?;
        // Charts: the ratios against size, and the times themselves.
        let series = |f: &dyn Fn(&Row) -> f64, dim: usize, threads: usize| -> Vec<(f64, f64)> {
            rows.iter()
                .filter(|r| r.dim == dim && r.threads == threads)
                .map(|r| (r.nodes as f64, f(r)))
                .collect()
        };
        let mut ratio = Vec::new();
        for (k, (dim, t)) in [(2, 1), (3, 1), (2, 2), (3, 2)].into_iter().enumerate() {
            let th = if t == 1 { "1 thread" } else { "2 threads" };
            ratio.push(Series::line(
                format!("{dim}D {th}: whole step"),
                series(&|r| r.penalty.step / r.augury.step, dim, t),
                k,
            ));
            ratio.push(Series::reference(
                format!("{dim}D {th}: contact part"),
                series(&|r| r.penalty.contact / r.augury.contact, dim, t),
                k,
            ));
        }
        let (lo, hi) = (
            rows.iter().map(|r| r.nodes).min().unwrap_or(1) as f64,
            rows.iter().map(|r| r.nodes).max().unwrap_or(1) as f64,
        );
        ratio.push(Series::line(
            "1× (as fast as the baseline)",
            vec![(lo, 1.0), (hi, 1.0)],
            5,
        ));
        ratio.push(Series::reference(
            format!("goals at 10⁵ nodes: {GOAL_STEP}× whole step, {GOAL_CONTACT}× contact"),
            vec![(1e5, GOAL_STEP), (1e5, GOAL_CONTACT)],
            5,
        ));
        ratio.push(Series::reference(
            "the paper: about 10× in serial",
            vec![(lo, 10.0), (hi, 10.0)],
            4,
        ));
        let png = charts::write_styled(
            &ctx.charts,
            &Chart {
                stem: format!("augury_speed_{}", ctx.tier.name()),
                title:
                    "Augury contact against the penalty baseline: speed-up (penalty time / augury time)"
                        .into(),
                x_label: "boundary nodes".into(),
                y_label: "speed-up of augury (×)".into(),
                series: ratio,
            },
            Style {
                log_x: true,
                log_y: true,
                markers: true,
                no_lines: false,
                legend: Corner::UpperLeft,
            },
        )?;
        out.charts.push((
            "Speed-up of augury over the penalty baseline, whole step (solid) and contact part (dashed); issue 43's goals at 10⁵ nodes: 2× and 5×".into(),
            png,
        ));
        let mut times = Vec::new();
        for (k, dim) in [2usize, 3].into_iter().enumerate() {
            for (j, (name, pick)) in [
                ("augury", (|r: &Row| r.augury.step) as fn(&Row) -> f64),
                ("penalty", |r: &Row| r.penalty.step),
            ]
            .into_iter()
            .enumerate()
            {
                times.push(Series::line(
                    format!("{dim}D {name}, 1 thread"),
                    series(&|r| pick(r) * 1e3, dim, 1),
                    2 * k + j,
                ));
                times.push(Series::reference(
                    format!("{dim}D {name}, 2 threads"),
                    series(&|r| pick(r) * 1e3, dim, 2),
                    2 * k + j,
                ));
            }
        }
        let png = charts::write_styled(
            &ctx.charts,
            &Chart {
                stem: format!("augury_speed_time_{}", ctx.tier.name()),
                title: "One explicit step of two facing plates: wall time".into(),
                x_label: "boundary nodes".into(),
                y_label: "ms per step".into(),
                series: times,
            },
            Style {
                log_x: true,
                log_y: true,
                markers: true,
                no_lines: false,
                legend: Corner::UpperRight,
            },
        )?;
        out.charts.push((
            "Wall time of one step (elastic forces and contact), 1 thread solid, 2 threads dashed"
                .into(),
            png,
        ));
        Ok(())
    }
}

/// A measured case: (boundary nodes, dimension), (every step the same, timings).
type Run = ((usize, usize), (bool, Vec<Row>));

/// Every timing of `runs`, by dimension, threads and size; an error if nothing was timed.
fn sorted_rows(runs: &[Run]) -> Result<Vec<Row>> {
    let mut rows: Vec<Row> = runs
        .iter()
        .flat_map(|(_, (_, r))| r.iter().cloned())
        .collect();
    if rows.is_empty() {
        bail!("nothing was timed");
    }
    rows.sort_by_key(|r| (r.dim, r.threads, r.nodes));
    Ok(rows)
}
