//! What an experiment produces: checks (the table's rows) with their status, charts, notes and
//! pictures, per tier.

use std::path::PathBuf;

/// Resolution tier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Tier {
    /// Coarse, minutes (CI).
    Quick,
    /// The papers' parameters.
    Full,
}

impl Tier {
    pub(super) fn name(self) -> &'static str {
        match self {
            Tier::Quick => "quick",
            Tier::Full => "full",
        }
    }
}

/// Outcome of one check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Status {
    /// Within tolerance.
    Pass,
    /// Outside tolerance.
    Fail,
    /// A figure reported against the paper without a pass/fail criterion (say why in `note`).
    Info,
}

impl Status {
    pub(super) fn label(self) -> &'static str {
        match self {
            Status::Pass => "PASS",
            Status::Fail => "FAIL",
            Status::Info => "INFO",
        }
    }
}

/// One row of the table.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Check {
    /// What is measured.
    pub figure: String,
    /// Measured value, formatted.
    pub measured: String,
    /// Expected value, formatted.
    pub expected: String,
    /// Tolerance, formatted.
    pub tolerance: String,
    /// Outcome.
    pub status: Status,
}

impl Check {
    /// `|measured − expected| ≤ tol` (absolute).
    pub fn abs(figure: &str, measured: f64, expected: f64, tol: f64, unit: &str) -> Self {
        let ok = (measured - expected).abs() <= tol;
        Self {
            figure: figure.into(),
            measured: format!("{measured:.6e}{unit}"),
            expected: format!("{expected:.6e}{unit}"),
            tolerance: format!("± {tol:.1e}{unit}"),
            status: if ok { Status::Pass } else { Status::Fail },
        }
    }

    /// `|measured − expected| ≤ rel · |expected|`.
    pub fn rel(figure: &str, measured: f64, expected: f64, rel: f64, unit: &str) -> Self {
        let ok = (measured - expected).abs() <= rel * expected.abs();
        Self {
            figure: figure.into(),
            measured: format!("{measured:.6e}{unit}"),
            expected: format!("{expected:.6e}{unit}"),
            tolerance: format!("± {:.2e} rel", rel),
            status: if ok { Status::Pass } else { Status::Fail },
        }
    }

    /// `measured ≤ bound`.
    pub fn at_most(figure: &str, measured: f64, bound: f64, unit: &str) -> Self {
        Self {
            figure: figure.into(),
            measured: format!("{measured:.3e}{unit}"),
            expected: format!("≤ {bound:.3e}{unit}"),
            tolerance: "—".into(),
            status: if measured <= bound {
                Status::Pass
            } else {
                Status::Fail
            },
        }
    }

    /// A count that must be exactly `expected`.
    pub fn count(figure: &str, measured: usize, expected: usize) -> Self {
        Self {
            figure: figure.into(),
            measured: measured.to_string(),
            expected: expected.to_string(),
            tolerance: "exact".into(),
            status: if measured == expected {
                Status::Pass
            } else {
                Status::Fail
            },
        }
    }

    /// A run that should have reached `expected` but stopped at `measured`: always a failure.
    pub fn stopped(figure: String, measured: String, expected: String) -> Self {
        Self {
            figure,
            measured,
            expected,
            tolerance: "—".into(),
            status: Status::Fail,
        }
    }

    /// A condition that must hold (`ok`), with how it was measured.
    pub fn holds(
        figure: &str,
        measured: String,
        expected: &str,
        tolerance: &str,
        ok: bool,
    ) -> Self {
        Self {
            figure: figure.into(),
            measured,
            expected: expected.into(),
            tolerance: tolerance.into(),
            status: if ok { Status::Pass } else { Status::Fail },
        }
    }

    /// A reported figure.
    pub fn info(figure: &str, measured: String, expected: String) -> Self {
        Self {
            figure: figure.into(),
            measured,
            expected,
            tolerance: "—".into(),
            status: Status::Info,
        }
    }
}

/// What one experiment produced.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Outcome {
    /// Rows of the table.
    pub checks: Vec<Check>,
    /// Charts (PNG paths, relative to the output directory).
    pub charts: Vec<(String, PathBuf)>,
    /// Plain-language notes for the report (where a result differs from the paper, and by how
    /// much; what the scene is).
    pub notes: Vec<String>,
    /// Scene pictures: a caption and its images (key frames, then an animation), shown in a row.
    pub pictures: Vec<(String, Vec<PathBuf>)>,
}
