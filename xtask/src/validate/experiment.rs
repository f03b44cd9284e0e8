//! The four parts every experiment of the suite has, and the one driver that runs them.

use anyhow::Result;

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

/// Run experiment `E` at `ctx`'s tier: every case measured in order, then its checks and charts.
/// A run that fails stops the experiment with its error (what it wrote so far stays in
/// `ctx.dir`).
pub fn drive<E: Experiment>(ctx: &Ctx) -> Result<Outcome> {
    let e = E::default();
    let mut runs = Vec::new();
    for case in e.cases(ctx)? {
        let measured = e.measure(ctx, &case)?;
        runs.push((case, measured));
    }
    let mut out = Outcome::default();
    e.checks(ctx, &runs, &mut out)?;
    e.charts(ctx, &runs, &mut out)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use super::*;
    use crate::validate::{Check, Tier};

    /// Records what the driver asks for, in order; case 3 fails to run.
    #[derive(Default)]
    struct Recorder {
        calls: RefCell<Vec<String>>,
    }

    impl Experiment for Recorder {
        type Case = usize;
        type Measured = f64;

        fn cases(&self, ctx: &Ctx) -> Result<Vec<usize>> {
            self.calls
                .borrow_mut()
                .push(format!("cases {}", ctx.tier.name()));
            Ok(if ctx.tier == Tier::Quick {
                vec![1, 2]
            } else {
                vec![1, 2, 3]
            })
        }

        fn measure(&self, _: &Ctx, &case: &usize) -> Result<f64> {
            self.calls.borrow_mut().push(format!("measure {case}"));
            anyhow::ensure!(case != 3, "case 3 stopped");
            Ok(case as f64 * 0.5)
        }

        fn checks(&self, _: &Ctx, runs: &[(usize, f64)], out: &mut Outcome) -> Result<()> {
            self.calls
                .borrow_mut()
                .push(format!("checks {}", runs.len()));
            for (case, m) in runs {
                out.checks
                    .push(Check::at_most(&format!("case {case}"), *m, 1.0, ""));
            }
            Ok(())
        }

        fn charts(&self, _: &Ctx, runs: &[(usize, f64)], out: &mut Outcome) -> Result<()> {
            self.calls
                .borrow_mut()
                .push(format!("charts {}", runs.len()));
            out.notes.push("charted".into());
            Ok(())
        }
    }

    fn ctx(tier: Tier) -> Ctx {
        let dir = std::env::temp_dir().join("femp-xtask-experiment-test");
        Ctx {
            tier,
            dir: dir.clone(),
            charts: dir,
            root: crate::validate::workspace_root(),
            progress: indicatif::MultiProgress::new(),
            pictured: Default::default(),
            settings: Vec::new(),
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
                CALLS.with(|c| c.borrow_mut().extend(self.0.calls.take()));
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
}
