//! The four parts every experiment of the suite has, and the one driver that runs them.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use anyhow::Result;

use super::ctx::in_case;
use super::{Ctx, Outcome};

/// One experiment: the cases (scenes and settings) a tier runs, what a run of one case measures,
/// the table rows and notes those measurements give, and the charts. [`drive`] runs the cases in
/// order, then asks for the checks and the charts of all of them; the analysis two experiments
/// share is in `validate/analysis/`.
pub trait Experiment: Default {
    /// What one run is given.
    type Case;
    /// What one run measured.
    type Measured;

    /// The cases of `ctx`'s tier, in the order they run.
    fn cases(&self, ctx: &Ctx) -> Result<Vec<Self::Case>>;

    /// Run `case` (its scenes, through `ctx`) and measure it.
    fn measure(&self, ctx: &Ctx, case: &Self::Case) -> Result<Self::Measured>;

    /// The rows of the table and the notes the measured cases give, into `out`.
    fn checks(
        &self,
        ctx: &Ctx,
        runs: &[(Self::Case, Self::Measured)],
        out: &mut Outcome,
    ) -> Result<()>;

    /// The charts of the measured cases, written under `ctx.charts` and listed in `out`.
    fn charts(
        &self,
        ctx: &Ctx,
        runs: &[(Self::Case, Self::Measured)],
        out: &mut Outcome,
    ) -> Result<()>;
}

/// Run experiment `E` at `ctx`'s tier: every case measured, then its checks and charts. A run
/// that fails stops the experiment with its error (what it wrote so far stays in `ctx.dir`).
/// With `ctx.case_lanes` > 1 the cases run in that many lanes at once ([`measure_in_lanes`]);
/// the checks and charts see them in order either way.
pub fn drive<E>(ctx: &Ctx) -> Result<Outcome>
where
    E: Experiment + Sync,
    E::Case: Sync,
    E::Measured: Send,
{
    let e = E::default();
    let cases = e.cases(ctx)?;
    let lanes = ctx.case_lanes.min(cases.len());
    let mut out = Outcome::default();
    let measured = if lanes > 1 {
        let threads = (rayon::current_num_threads() / lanes).max(1);
        let measured = measure_in_lanes(&e, ctx, &cases, (lanes, threads))?;
        out.notes.push(format!(
            "The {} cases ran in {lanes} lanes at once (`--jobs {lanes}`), {threads} thread{} \
             each, the longest first: the wall time is the longest lane's; each run's own is in \
             its summary.json.",
            cases.len(),
            if threads == 1 { "" } else { "s" }
        ));
        measured
    } else {
        let mut measured = Vec::with_capacity(cases.len());
        for (k, case) in cases.iter().enumerate() {
            measured.push(in_case(k, || e.measure(ctx, case))?);
        }
        measured
    };
    let runs: Vec<_> = cases.into_iter().zip(measured).collect();
    e.checks(ctx, &runs, &mut out)?;
    e.charts(ctx, &runs, &mut out)?;
    Ok(out)
}

/// The cases of `e` measured in `lanes` threads, each with a rayon pool of `threads`: each lane
/// takes the next case not yet taken, from the last (an experiment's later cases are its finer
/// or harder ones: the longest start first). Once a case fails no lane starts another, and the
/// error of the first failed case in case order is returned. The measurements in case order.
fn measure_in_lanes<E>(
    e: &E,
    ctx: &Ctx,
    cases: &[E::Case],
    (lanes, threads): (usize, usize),
) -> Result<Vec<E::Measured>>
where
    E: Experiment + Sync,
    E::Case: Sync,
    E::Measured: Send,
{
    let pools = (0..lanes)
        .map(|_| rayon::ThreadPoolBuilder::new().num_threads(threads).build())
        .collect::<Result<Vec<_>, _>>()?;
    let taken = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let results: Vec<Mutex<Option<Result<E::Measured>>>> =
        cases.iter().map(|_| Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for pool in &pools {
            let (taken, failed, results) = (&taken, &failed, &results);
            scope.spawn(move || {
                while !failed.load(Ordering::SeqCst) {
                    let t = taken.fetch_add(1, Ordering::SeqCst);
                    if t >= cases.len() {
                        break;
                    }
                    let k = cases.len() - 1 - t;
                    let r = pool.install(|| in_case(k, || e.measure(ctx, &cases[k])));
                    if r.is_err() {
                        failed.store(true, Ordering::SeqCst);
                    }
                    *results[k].lock().expect("a lane panicked") = Some(r);
                }
            });
        }
    });
    let results: Vec<Option<Result<E::Measured>>> = results
        .into_iter()
        .map(|r| r.into_inner().expect("a lane panicked"))
        .collect();
    if failed.load(Ordering::SeqCst) {
        let first = results.into_iter().flatten().find_map(Result::err);
        return Err(first.expect("a failed case stored its error"));
    }
    results
        .into_iter()
        .map(|r| r.expect("every case ran: none failed"))
        .collect()
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;
    use std::time::{Duration, Instant};

    use super::*;
    use crate::validate::{Check, Pictures, Tier};

    /// Records what the driver asks for, in order; case 3 fails to run.
    #[derive(Default)]
    struct Recorder {
        calls: Mutex<Vec<String>>,
    }

    impl Experiment for Recorder {
        type Case = usize;
        type Measured = f64;

        fn cases(&self, ctx: &Ctx) -> Result<Vec<usize>> {
            self.calls
                .lock()
                .unwrap()
                .push(format!("cases {}", ctx.tier.name()));
            Ok(if ctx.tier == Tier::Quick {
                vec![1, 2]
            } else {
                vec![1, 2, 3]
            })
        }

        fn measure(&self, _: &Ctx, &case: &usize) -> Result<f64> {
            self.calls.lock().unwrap().push(format!("measure {case}"));
            anyhow::ensure!(case != 3, "case 3 stopped");
            Ok(case as f64 * 0.5)
        }

        fn checks(&self, _: &Ctx, runs: &[(usize, f64)], out: &mut Outcome) -> Result<()> {
            self.calls
                .lock()
                .unwrap()
                .push(format!("checks {}", runs.len()));
            for (case, m) in runs {
                out.checks
                    .push(Check::at_most(&format!("case {case}"), *m, 1.0, ""));
            }
            Ok(())
        }

        fn charts(&self, _: &Ctx, runs: &[(usize, f64)], out: &mut Outcome) -> Result<()> {
            self.calls
                .lock()
                .unwrap()
                .push(format!("charts {}", runs.len()));
            out.notes.push("charted".into());
            Ok(())
        }
    }

    fn ctx(tier: Tier) -> Ctx {
        let dir = std::env::temp_dir().join(format!("femp-xtask-experiment-test-{tier:?}"));
        Ctx {
            tier,
            dir: dir.clone(),
            charts: dir,
            root: crate::validate::workspace_root(),
            progress: indicatif::MultiProgress::new(),
            pictured: Default::default(),
            settings: Vec::new(),
            case_lanes: 1,
            resume: false,
        }
    }

    /// `drive` measures every case in order, then asks for the checks and the charts of all of
    /// them, and a case that fails stops the experiment with its error.
    #[test]
    fn the_driver_measures_every_case_then_checks_and_charts_them() {
        thread_local!(static CALLS: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) });
        // `drive` makes its own experiment: record through a wrapper that copies its calls out.
        #[derive(Default)]
        struct Shared(Recorder);
        impl Drop for Shared {
            fn drop(&mut self) {
                let calls = std::mem::take(&mut *self.0.calls.lock().unwrap());
                CALLS.with(|c| c.borrow_mut().extend(calls));
            }
        }
        impl Experiment for Shared {
            type Case = usize;
            type Measured = f64;
            fn cases(&self, ctx: &Ctx) -> Result<Vec<usize>> {
                self.0.cases(ctx)
            }
            fn measure(&self, ctx: &Ctx, case: &usize) -> Result<f64> {
                self.0.measure(ctx, case)
            }
            fn checks(&self, ctx: &Ctx, r: &[(usize, f64)], out: &mut Outcome) -> Result<()> {
                self.0.checks(ctx, r, out)
            }
            fn charts(&self, ctx: &Ctx, r: &[(usize, f64)], out: &mut Outcome) -> Result<()> {
                self.0.charts(ctx, r, out)
            }
        }
        let out = drive::<Shared>(&ctx(Tier::Quick)).unwrap();
        let calls = CALLS.with(|c| c.take());
        assert_eq!(
            calls,
            [
                "cases quick",
                "measure 1",
                "measure 2",
                "checks 2",
                "charts 2"
            ]
        );
        let figures: Vec<&str> = out.checks.iter().map(|c| c.figure.as_str()).collect();
        assert_eq!(figures, ["case 1", "case 2"]);
        assert_eq!(out.notes, ["charted"]);

        let e = drive::<Shared>(&ctx(Tier::Full)).unwrap_err();
        assert_eq!(e.to_string(), "case 3 stopped");
        let calls = CALLS.with(|c| c.take());
        assert_eq!(
            calls,
            ["cases full", "measure 1", "measure 2", "measure 3"],
            "no checks or charts after a failed run"
        );
    }

    /// Five cases, each asking for pictures; case `fails` fails. The first two cases a lane
    /// takes (4 and 3) wait for each other, so they can only finish if they run at once.
    #[derive(Default)]
    struct Lanes {
        fails: Option<usize>,
        arrived: AtomicUsize,
        met: AtomicUsize,
    }

    impl Experiment for Lanes {
        type Case = usize;
        type Measured = (usize, usize);

        fn cases(&self, _: &Ctx) -> Result<Vec<usize>> {
            Ok((0..5).collect())
        }

        fn measure(&self, ctx: &Ctx, &case: &usize) -> Result<(usize, usize)> {
            ctx.picture_options(
                &format!("run{case}"),
                Some(Pictures::keys(format!("case {case}"), 2)),
            );
            if case >= 3 {
                self.arrived.fetch_add(1, Ordering::SeqCst);
                let start = Instant::now();
                while self.arrived.load(Ordering::SeqCst) < 2 {
                    if start.elapsed() > Duration::from_secs(20) {
                        anyhow::bail!("case {case} ran alone");
                    }
                    std::thread::sleep(Duration::from_millis(1));
                }
                self.met.fetch_add(1, Ordering::SeqCst);
            }
            anyhow::ensure!(Some(case) != self.fails, "case {case} stopped");
            Ok((case, rayon::current_num_threads()))
        }

        fn checks(
            &self,
            _: &Ctx,
            runs: &[(usize, (usize, usize))],
            out: &mut Outcome,
        ) -> Result<()> {
            assert_eq!(
                self.met.load(Ordering::SeqCst),
                2,
                "cases 4 and 3 ran at once"
            );
            for (case, (measured, threads)) in runs {
                out.notes.push(format!("{case} {measured} {threads}"));
            }
            Ok(())
        }

        fn charts(&self, _: &Ctx, _: &[(usize, (usize, usize))], _: &mut Outcome) -> Result<()> {
            Ok(())
        }
    }

    /// With `case_lanes` 2 the cases run two at once, each lane in a one-thread pool here
    /// (`drive` gives each lane its share of the caller's threads), and the checks see every
    /// case's measurement in case order; the pictures are listed in case order too. A failed
    /// case stops the experiment with its error.
    #[test]
    fn lanes_measure_cases_at_once_and_report_them_in_order() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let mut c = ctx(Tier::Full);
        c.case_lanes = 2;
        let mut out = pool.install(|| drive::<Lanes>(&c)).unwrap();
        assert_eq!(
            out.notes[0].split(':').next().unwrap(),
            "The 5 cases ran in 2 lanes at once (`--jobs 2`), 1 thread each, the longest first"
        );
        assert_eq!(
            out.notes[1..],
            ["0 0 1", "1 1 1", "2 2 1", "3 3 1", "4 4 1"]
        );
        c.collect_pictures(&mut out).unwrap();
        let captions: Vec<&str> = out.pictures.iter().map(|p| p.0.as_str()).collect();
        assert_eq!(captions, ["case 0", "case 1", "case 2", "case 3", "case 4"]);

        #[derive(Default)]
        struct Failing;
        impl Experiment for Failing {
            type Case = usize;
            type Measured = (usize, usize);
            fn cases(&self, _: &Ctx) -> Result<Vec<usize>> {
                Ok((0..5).collect())
            }
            fn measure(&self, _: &Ctx, &case: &usize) -> Result<(usize, usize)> {
                anyhow::ensure!(case != 4, "case {case} stopped");
                Ok((case, 0))
            }
            fn checks(
                &self,
                _: &Ctx,
                _: &[(usize, (usize, usize))],
                _: &mut Outcome,
            ) -> Result<()> {
                panic!("no checks after a failed case")
            }
            fn charts(
                &self,
                _: &Ctx,
                _: &[(usize, (usize, usize))],
                _: &mut Outcome,
            ) -> Result<()> {
                panic!("no charts after a failed case")
            }
        }
        let e = pool.install(|| drive::<Failing>(&c)).unwrap_err();
        assert_eq!(e.to_string(), "case 4 stopped");
    }
}
