//! The scene file format: serde types mirroring the JSON, field by field (documented in
//! `docs/scenes.md`). Unknown fields are errors. Vectors are plain arrays whose length must
//! equal the scene's dimension (checked by [`super::parse`]).

use serde::{Deserialize, Serialize};

/// A whole scene file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// Name (defaults to the file stem).
    #[serde(default)]
    pub name: Option<String>,
    /// 2 or 3.
    pub dimension: usize,
    /// Which method simulates the scene.
    #[serde(default)]
    pub method: Method,
    /// Gravitational acceleration (m/s²), one entry per axis. Default zero.
    #[serde(default)]
    pub gravity: Option<Vec<f64>>,
    /// Time stepping.
    pub time: TimeSpec,
    /// Newton and friction iteration settings.
    #[serde(default)]
    pub solver: SolverSpec,
    /// MPM grid and transfer (required if any body is MPM).
    #[serde(default)]
    pub mpm: Option<MpmSpec>,
    /// The bodies.
    pub bodies: Vec<BodySpec>,
    /// Contact parameters (required if the scene has both MPM and FEM bodies, or several FEM
    /// bodies).
    #[serde(default)]
    pub contact: Option<ContactSpec>,
    /// Level-set boundaries acting on the MPM grid.
    #[serde(default)]
    pub boundaries: Vec<BoundarySpec>,
    /// Settings of the `augury` method (only with `"method": "augury"`; defaults if absent).
    #[serde(default)]
    pub augury: Option<AugurySpec>,
}

/// Settings of the `augury` method: explicit central differences with APIC augury contact on a
/// background grid (or the search-based penalty baseline).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AugurySpec {
    /// Background grid spacing (m). Give this or `grid_ratio`, not both.
    #[serde(default)]
    pub grid_spacing: Option<f64>,
    /// Background grid spacing as a multiple of the mean boundary edge length of the bodies
    /// (default 2, the paper's choice).
    #[serde(default)]
    pub grid_ratio: Option<f64>,
    /// B-spline kernel.
    #[serde(default)]
    pub kernel: KernelSpec,
    /// `"apic"` (default) or `"pic"`.
    #[serde(default)]
    pub transfer: AuguryTransferSpec,
    /// Look-ahead time τ (s); default Δt.
    #[serde(default)]
    pub tau: Option<f64>,
    /// Augury iterations N (default 1, the paper's choice).
    #[serde(default = "one_usize")]
    pub iterations: usize,
    /// What the iterations undo.
    #[serde(default)]
    pub model: AuguryModelSpec,
    /// Coulomb coefficient μ for `"model": "friction"` (default 0: frictionless).
    #[serde(default)]
    pub friction: f64,
    /// Which contact handling: augury (default), the penalty baseline, or none.
    #[serde(default)]
    pub contact: AuguryContactSpec,
    /// Settings of the penalty baseline (required with `"contact": "penalty"`).
    #[serde(default)]
    pub penalty: Option<PenaltySpec>,
    /// How fully prescribed bodies weigh in the correction (default `"lumped"`).
    #[serde(default)]
    pub obstacles: AuguryObstaclesSpec,
    /// Stop the run when a boundary vertex ends a step deeper inside another body than this
    /// fraction of that body's mean boundary edge, or passed through it over the step
    /// (default 0.5); `null`: never stop (studies of where the method lets bodies in).
    #[serde(default = "half")]
    pub penetration_limit: Option<f64>,
}

fn half() -> Option<f64> {
    Some(0.5)
}

/// How fully prescribed bodies (plates, walls) enter the augury correction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AuguryObstaclesSpec {
    /// With their lumped masses (the paper's formulation).
    #[default]
    Lumped,
    /// As infinitely heavy (holds normal loads; loses tangential sliding).
    Kinematic,
}

fn one_usize() -> usize {
    1
}

/// Quadratic B-spline kernel of the background grid.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KernelSpec {
    /// The standard 3-node-per-axis kernel, `D_p = ¼h²I`.
    #[default]
    Quadratic,
    /// The augury paper's 4-node variant (appendix B), `D_p = ½h²I`.
    Quadratic4,
}

/// Transfer of the augury correction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AuguryTransferSpec {
    /// APIC: conserves linear and angular momentum.
    #[default]
    Apic,
    /// PIC (`B_p ≡ 0`): conserves linear momentum.
    Pic,
}

/// The contact model of the augury iterations.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AuguryModelSpec {
    /// No iterations: bodies stick on contact.
    Sticky,
    /// Undo changes that pull particles away from their surface (eq. 38).
    Separation,
    /// Separation and Coulomb friction with `friction` (eqs. 42–46).
    #[default]
    Friction,
}

/// Contact handling of an augury scene.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AuguryContactSpec {
    /// APIC/PIC augury contact.
    #[default]
    Augury,
    /// The search-based node-to-surface penalty baseline.
    Penalty,
    /// No contact: bodies pass through each other.
    None,
}

/// The penalty baseline's parameters.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PenaltySpec {
    /// Force per unit penetration (N/m in 3D; N/m per unit thickness in 2D).
    pub stiffness: f64,
    /// Search band (m): vertices up to this far behind a facet are pushed out.
    pub band: f64,
}

/// The simulation method.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Implicit MPM–FEM coupling through barrier contact.
    #[default]
    Bfemp,
    /// Explicit FEM with APIC augury contact.
    Augury,
}

/// Time stepping.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Time step Δt (s).
    pub dt: f64,
    /// Simulated duration (s).
    pub duration: f64,
    /// Time integrator.
    #[serde(default)]
    pub integrator: IntegratorSpec,
    /// Seconds between output frames (default: every step).
    #[serde(default)]
    pub frame_interval: Option<f64>,
}

/// Integrator choice.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorSpec {
    /// Backward Euler.
    #[default]
    BackwardEuler,
    /// Newmark (trapezoidal).
    Newmark,
    /// Contact-stabilised Newmark (Deuflhard, Krause and Ertel 2008): Newmark whose predictor
    /// is first moved, in the mass norm, to the nearest configuration the barrier admits
    /// (inertia and barrier only), with contact forces implicit only (the stored acceleration
    /// carries no contact force). Newmark's step wherever no contact term is active.
    ContactStabilizedNewmark,
}

/// Solver settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSpec {
    /// Newton tolerance ε_d on ‖p‖∞/Δt (m/s).
    pub tolerance: f64,
    /// Newton iteration limit per solve.
    pub max_newton_iterations: usize,
    /// Friction (lagging) iteration limit per step.
    pub max_friction_iterations: usize,
    /// When the Newton iterations PSD-project element, particle and barrier Hessians.
    pub projection: ProjectionSpec,
    /// How the Newton direction is solved for.
    pub linear: LinearSpec,
    /// With `linear: "pcg"`: relative reduction of CG's preconditioned residual.
    pub pcg_rtol: f64,
    /// With `linear: "pcg"`: CG iterations before falling back to Cholesky.
    pub pcg_max_iterations: usize,
    /// With `linear: "last_factor_cg"`: relative reduction of CG's residual preconditioned
    /// with the last factor.
    pub factor_cg_rtol: f64,
    /// With `linear: "last_factor_cg"`: CG iterations before the matrix is factorised.
    pub factor_cg_iterations: usize,
    /// With `linear: "pcg"`: the largest relative reduction an iteration asks of CG, the
    /// Eisenstat–Walker forcing term choosing between it and `pcg_rtol` (`None`: every
    /// iteration to `pcg_rtol`).
    pub pcg_rtol_max: Option<f64>,
    /// Reuse the last Newton iteration's Hessian after a full step whose increment
    /// ‖p‖∞/Δt was below this (m/s) while the contact set is unchanged (0: never).
    pub reuse_hessian_below: f64,
    /// Newton iterations re-evaluate the lagged friction operator at their iterate once an
    /// increment ‖p‖∞/Δt is below this (m/s; 0: only between solves, Algorithm 1).
    pub friction_update_below: f64,
    /// Once the friction loop's first solve has converged, its later solves re-evaluate the
    /// operator at every Newton iterate after their first while that contracts — each
    /// iteration's increment below 0.9 of the last one's; from the first that is not, this
    /// step's operator moves only between solves again (where Aitken's relaxation damps a
    /// loop that oscillates). The loop ends at the same fixed point, to the same tolerance.
    /// `None`: [`SolverSpec::update_later`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction_update_later: Option<bool>,
    /// The forcing η of inexact friction solves: while the friction operator still moves, a
    /// solve stops at `max(tolerance, η × its last change)` (m/s); the last solve is to the full
    /// tolerance — or ended below it anyway (0: every solve to the full tolerance). `None`:
    /// [`SolverSpec::forcing`] — 0.3 in 3D, 0 in 2D.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction_forcing: Option<f64>,
    /// Aitken extrapolation of the friction loop: once two solves in a row have shrunk the
    /// operator's change by a steady ratio r < 0.9, the operator is lagged at
    /// `x + r/(1 − r) (x − its last point)` (where the straight path there is feasible)
    /// instead of at the solve's `x`; the loop still ends only at a fixed point.
    #[serde(skip_serializing_if = "is_false")]
    pub friction_extrapolation: bool,
    /// Once a solve's change of the friction operator's point is not below the previous
    /// solve's (the loop has stopped contracting), lag every later operator half way from its
    /// last point to the solve's `x` (averaged fixed-point iteration; the same fixed points).
    #[serde(skip_serializing_if = "is_false")]
    pub friction_relaxation: bool,
    /// Lag every operator after the first at `lag + ω (x − lag)` with Aitken's dynamic factor
    /// (Irons–Tuck) `ω_k = −ω_{k−1} d_{k−1}·(d_k − d_{k−1}) / ‖d_k − d_{k−1}‖²`, `d` the
    /// points' fixed-point residual, clamped to [1/16, 1]: a loop that oscillates is damped, one
    /// that contracts monotonically is lagged as plain (the same fixed points). `None`: on,
    /// unless `friction_relaxation` or `friction_extrapolation` chooses the lags instead
    /// ([`SolverSpec::aitken`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction_aitken: Option<bool>,
    /// Anderson acceleration of the friction loop with this many past iterates (0: off):
    /// each operator after the first is lagged where the last `m + 1` solves' residuals,
    /// combined by least squares, vanish to first order (Walker & Ni 2011, type II) — a
    /// multi-dimensional secant where Aitken's factor is one number. On, it chooses the lags
    /// instead of `friction_aitken`; a mixed lag that is not feasible from the solve's point
    /// is replaced by the plain one, and after one whose residual grew the history restarts
    /// from a plain lag. The same fixed points. `None`:
    /// [`SolverSpec::anderson`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction_anderson: Option<usize>,
    /// A Newton direction that carries friction terms through their stick zone (sliding now,
    /// past the zone's centre at the step's end) is solved again with those terms modelled
    /// as stuck — the stick zone's quadratic instead of the Taylor expansion at their slip —
    /// and taken if it descends the energy: the solve lands in the stick zone instead of
    /// creeping to its kink over cut steps. Each solve's minimiser is the same.
    pub friction_stick_model: bool,
    /// The longest step the line search may take, in multiples of the Newton step: a full
    /// step that decreased the energy by at least 3/4 of the first-order prediction (the
    /// energy much flatter along the direction than the projected Hessian says) is doubled
    /// while the energy keeps falling, within the CCD and det F bounds (1: never beyond the
    /// Newton step). Only a projected Hessian's step expands. Default 64.
    pub line_search_expansion: f64,
    /// What Newton's convergence test measures the increment on.
    pub newton_test: NewtonTestSpec,
    /// When a step's Newton solve fails (iteration limit, stalled line search), solve the step
    /// again from its start with the other `projection`; the step fails only if both do.
    pub retry_other_projection: bool,
    /// The fill-reducing ordering of the sparse Cholesky factorisations.
    pub ordering: OrderingSpec,
    /// The arithmetic of the sparse Cholesky factorisations.
    pub factor_precision: PrecisionSpec,
    /// The most substeps a step may be split into when a point's straight path over it would
    /// pass through a body ([`crate::sweep`]): the step is solved again as 2, 4, 8, … substeps
    /// up to this many; 1 never splits (such a step fails at once).
    pub max_substeps: usize,
}

/// The fill-reducing ordering of the Newton systems' Cholesky factorisations
/// (`solver.ordering`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OrderingSpec {
    /// Nested dissection in 3D, approximate minimum degree in 2D.
    #[default]
    Auto,
    /// Approximate minimum degree (faer's).
    Amd,
    /// Nested dissection (METIS), on the D×D blocks of the unknowns.
    NestedDissection,
}

/// The arithmetic of the Newton systems' Cholesky factorisations (`solver.factor_precision`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PrecisionSpec {
    /// `mixed` where the factor is large (more than 2·10⁷ entries, over 300 a row: 3D systems
    /// of 20 000 unknowns and more), `double` otherwise. The default.
    #[default]
    Auto,
    /// Factors and solves in double precision.
    Double,
    /// Factors in single precision (the matrix scaled to a unit diagonal), every solve refined
    /// to double precision by conjugate gradients preconditioned with the factor; a matrix it
    /// cannot solve so is factorised in double precision.
    Mixed,
}

/// What Newton's convergence test `‖p‖/Δt < tolerance` measures (`solver.newton_test`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NewtonTestSpec {
    /// The largest increment of any unknown — grid node or FEM vertex (BFEMP §5's test).
    Nodes,
    /// The largest increment of what the unknowns move: each particle's position and, times
    /// the grid spacing, its deformation gradient; each FEM vertex. The default.
    #[default]
    Points,
}

/// The Newton direction's linear solver (`solver.linear`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LinearSpec {
    /// `last_factor_cg` where the factor is large (as `factor_precision: "auto"`),
    /// `cholesky` otherwise. The default.
    #[default]
    Auto,
    /// Sparse Cholesky of every Hessian.
    Cholesky,
    /// Jacobi-preconditioned conjugate gradients, Cholesky when CG cannot.
    Pcg,
    /// Cholesky once a solve, then CG preconditioned with the last factor (factorising again
    /// when CG needs too many iterations).
    LastFactorCg,
}

/// When the Newton iterations PSD-project the Hessian (`solver.projection`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProjectionSpec {
    /// Every iteration (projected Newton; the papers' method).
    Always,
    /// Only when the exact Hessian of the whole system is indefinite: an iteration factorises
    /// the exact one if it is positive definite, else the projected one. The default.
    #[default]
    WhenIndefinite,
}

impl SolverSpec {
    /// `friction_forcing` where the scene leaves it out, in 3D: a 3D Newton iteration is a
    /// large factorisation, and the 3D benchmarks' friction loops all converge with it (§6.7's
    /// twist: 21 % fewer Newton iterations, block_on_plate_3d's contact step 24 → 13). In 2D
    /// the quick tier's buckling rings and Hertz disk end more loops unconverged with it, so
    /// there it is 0 (docs/performance.md).
    pub const AUTO_FORCING_3D: f64 = 0.3;

    /// The forcing η of the friction loop's inexact solves in a `dimension`-D scene: as set,
    /// else [`Self::AUTO_FORCING_3D`] in 3D and 0 (every solve exact) in 2D.
    pub fn forcing(&self, dimension: usize) -> f64 {
        self.friction_forcing.unwrap_or(if dimension == 3 {
            Self::AUTO_FORCING_3D
        } else {
            0.0
        })
    }

    /// Whether the friction loop's later solves update the operator inside Newton
    /// (`friction_update_later`): as set, else in 3D only.
    pub fn update_later(&self, dimension: usize) -> bool {
        self.friction_update_later.unwrap_or(dimension == 3)
    }

    /// Whether the friction loop lags with Aitken's dynamic relaxation: as set, else unless
    /// `friction_relaxation` or `friction_extrapolation` is on.
    pub fn aitken(&self, dimension: usize) -> bool {
        self.friction_aitken.unwrap_or(
            !(self.friction_relaxation
                || self.friction_extrapolation
                || self.anderson(dimension) > 0),
        )
    }

    /// `friction_anderson` where the scene leaves it out, in 3D: the §6.7 twist's friction
    /// loops at h = 0.125 end in at most 55 Newton iterations with it (101 and 106 without)
    /// and 1 of 1 100 unconverged (7); block_on_plate_3d is unchanged; the quick tier's twist
    /// (Δt five times the paper's) ends one loop unconverged with it (none without). In 2D the
    /// quick tier's friction experiments end one loop more unconverged with it, so there it is
    /// off (docs/performance.md).
    pub const AUTO_ANDERSON_3D: usize = 3;

    /// The friction loop's Anderson depth in a `dimension`-D scene (`friction_anderson`): as
    /// set, else [`Self::AUTO_ANDERSON_3D`] in 3D unless the scene chooses the lags otherwise
    /// (`friction_aitken: true`, `friction_relaxation`, `friction_extrapolation`), 0 (off) in
    /// 2D.
    pub fn anderson(&self, dimension: usize) -> usize {
        self.friction_anderson.unwrap_or(
            if dimension == 3
                && self.friction_aitken != Some(true)
                && !(self.friction_relaxation || self.friction_extrapolation)
            {
                Self::AUTO_ANDERSON_3D
            } else {
                0
            },
        )
    }

    /// The most past iterates `friction_anderson` may mix (each a copy of the unknowns and of
    /// the points; the loop has at most `max_friction_iterations` anyway).
    pub const ANDERSON_MAX: usize = 16;

    /// The fill-reducing ordering in a `dimension`-D scene: as set, else nested dissection in
    /// 3D and AMD in 2D (measured: docs/performance.md).
    pub fn ordering_in(&self, dimension: usize) -> OrderingSpec {
        match self.ordering {
            OrderingSpec::Auto if dimension == 3 => OrderingSpec::NestedDissection,
            OrderingSpec::Auto => OrderingSpec::Amd,
            set => set,
        }
    }

    /// These settings with every choice femp makes where the scene leaves one open filled in
    /// for a `dimension`-D scene (`friction_forcing`, `friction_update_later`,
    /// `friction_aitken`, `friction_anderson`, `ordering`): what a run actually used. A checkpoint records it, so a
    /// femp whose defaults have changed since refuses to continue the run under other settings
    /// (`World::restore`). `linear` and `factor_precision` stay `auto`: they choose per system
    /// as it comes.
    pub fn resolved(&self, dimension: usize) -> SolverSpec {
        SolverSpec {
            friction_forcing: Some(self.forcing(dimension)),
            friction_update_later: Some(self.update_later(dimension)),
            friction_aitken: Some(self.aitken(dimension)),
            friction_anderson: Some(self.anderson(dimension)),
            ordering: self.ordering_in(dimension),
            ..self.clone()
        }
    }
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self {
            tolerance: 1e-4,
            max_newton_iterations: 100,
            max_friction_iterations: 20,
            projection: ProjectionSpec::WhenIndefinite,
            linear: LinearSpec::Auto,
            pcg_rtol: 1e-6,
            pcg_max_iterations: 200,
            factor_cg_rtol: 1e-3,
            factor_cg_iterations: 16,
            pcg_rtol_max: None,
            reuse_hessian_below: 0.0,
            friction_update_below: 0.0,
            friction_update_later: None,
            friction_forcing: None,
            friction_extrapolation: false,
            friction_relaxation: false,
            friction_aitken: None,
            friction_anderson: None,
            friction_stick_model: true,
            line_search_expansion: 64.0,
            newton_test: NewtonTestSpec::Points,
            retry_other_projection: true,
            max_substeps: 1024,
            ordering: OrderingSpec::Auto,
            factor_precision: PrecisionSpec::Auto,
        }
    }
}

/// MPM settings shared by all MPM bodies.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MpmSpec {
    /// Grid spacing h (m).
    pub grid_spacing: f64,
    /// Particle–grid transfer.
    #[serde(default)]
    pub transfer: TransferSpec,
    /// FLIP fraction for `"flip"` (1 = pure FLIP).
    #[serde(default = "one")]
    pub flip_ratio: f64,
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn one() -> f64 {
    1.0
}

/// Particle–grid transfer.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TransferSpec {
    /// Affine particle-in-cell.
    #[default]
    Apic,
    /// Particle-in-cell.
    Pic,
    /// Fluid-implicit-particle (with `flip_ratio`).
    Flip,
}

/// A material.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Constitutive model.
    #[serde(default)]
    pub model: ModelSpec,
    /// Young's modulus E (Pa).
    #[serde(rename = "E")]
    pub youngs_modulus: f64,
    /// Poisson's ratio ν.
    pub nu: f64,
    /// Density ρ (kg/m³ in 3D, kg/m² in 2D).
    pub rho: f64,
}

/// Constitutive model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelSpec {
    /// Compressible neo-Hookean.
    #[default]
    NeoHookean,
    /// Small-strain linear elasticity.
    Linear,
}

/// Initial angular velocity: a scalar in 2D (about z), a vector in 3D.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(untagged)]
pub enum AngularSpec {
    /// 2D.
    Scalar(f64),
    /// 3D.
    Vector(Vec<f64>),
}

/// A rigid placement applied to a generated shape or mesh: rotate about `about` (default: the
/// origin), then translate.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TransformSpec {
    /// Rotation angle in degrees (2D: counter-clockwise; 3D: about `axis`).
    #[serde(default)]
    pub rotate_deg: f64,
    /// 3D rotation axis (default z).
    #[serde(default)]
    pub axis: Option<Vec<f64>>,
    /// Rotation centre (default origin).
    #[serde(default)]
    pub about: Option<Vec<f64>>,
    /// Translation.
    #[serde(default)]
    pub translate: Option<Vec<f64>>,
}

/// A body: `{"kind": "mpm", ...}` ([`MpmBody`]) or `{"kind": "fem", ...}` ([`FemBody`]).
///
/// Deserialised by hand (not with serde's internally tagged enums, which lose the path of an
/// error inside the body): errors name the full path, e.g. `bodies[0].material.Young`.
#[derive(Debug, Clone)]
pub enum BodySpec {
    /// Material points on the background grid.
    Mpm(MpmBody),
    /// A finite-element mesh.
    Fem(FemBody),
}

impl BodySpec {
    /// The body's name.
    pub fn name(&self) -> &str {
        match self {
            BodySpec::Mpm(b) => &b.name,
            BodySpec::Fem(b) => &b.name,
        }
    }
}

/// Prefix of a nested error message that carries the path inside a body (merged into the field
/// path by [`super::parse`]).
pub(crate) const NESTED_PATH: &str = "\u{1}";

/// Written as the body's fields and its `kind`, as read.
impl Serialize for BodySpec {
    fn serialize<S: serde::Serializer>(&self, se: S) -> Result<S::Ok, S::Error> {
        use serde::ser::Error;
        let (kind, body) = match self {
            BodySpec::Mpm(b) => ("mpm", serde_json::to_value(b)),
            BodySpec::Fem(b) => ("fem", serde_json::to_value(b)),
        };
        let serde_json::Value::Object(fields) = body.map_err(S::Error::custom)? else {
            return Err(S::Error::custom("a body serialises to an object"));
        };
        let mut map = serde_json::Map::with_capacity(fields.len() + 1);
        map.insert("kind".into(), kind.into());
        map.extend(fields);
        map.serialize(se)
    }
}

impl<'de> Deserialize<'de> for BodySpec {
    fn deserialize<De: serde::Deserializer<'de>>(de: De) -> Result<Self, De::Error> {
        use serde::de::Error;
        let mut v = serde_json::Value::deserialize(de)?;
        let obj = v
            .as_object_mut()
            .ok_or_else(|| De::Error::custom("a body must be an object with a `kind`"))?;
        let kind = match obj.remove("kind") {
            None => return Err(De::Error::missing_field("kind")),
            Some(serde_json::Value::String(k)) => k,
            Some(other) => {
                return Err(De::Error::custom(format!(
                    "{NESTED_PATH}kind{NESTED_PATH}expected \"mpm\" or \"fem\", found {other}"
                )));
            }
        };
        let nested = |e: serde_path_to_error::Error<serde_json::Error>| {
            let path = e.path().to_string();
            De::Error::custom(format!(
                "{NESTED_PATH}{path}{NESTED_PATH}{}",
                e.into_inner()
            ))
        };
        match kind.as_str() {
            "mpm" => serde_path_to_error::deserialize(v)
                .map(BodySpec::Mpm)
                .map_err(nested),
            "fem" => serde_path_to_error::deserialize(v)
                .map(BodySpec::Fem)
                .map_err(nested),
            other => Err(De::Error::custom(format!(
                "{NESTED_PATH}kind{NESTED_PATH}unknown variant `{other}`, expected `mpm` or `fem`"
            ))),
        }
    }
}

/// An MPM body: material points filling a region, on the scene's background grid.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MpmBody {
    /// Unique name.
    pub name: String,
    /// Region filled with particles.
    pub shape: ShapeSpec,
    /// Particles per grid cell (a perfect square in 2D, cube in 3D). Default 4 / 8.
    #[serde(default)]
    pub particles_per_cell: Option<usize>,
    /// Material.
    pub material: MaterialSpec,
    /// Initial linear velocity.
    #[serde(default)]
    pub velocity: Option<Vec<f64>>,
    /// Initial angular velocity about the body's centre of mass.
    #[serde(default)]
    pub angular_velocity: Option<AngularSpec>,
}

/// A FEM body: a mesh, optionally placed, with vertex sets of prescribed motion.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FemBody {
    /// Unique name.
    pub name: String,
    /// The mesh.
    pub mesh: MeshSpec,
    /// Placement of the mesh.
    #[serde(default)]
    pub transform: Option<TransformSpec>,
    /// Material.
    pub material: MaterialSpec,
    /// Initial linear velocity.
    #[serde(default)]
    pub velocity: Option<Vec<f64>>,
    /// Initial angular velocity about the body's centre of mass.
    #[serde(default)]
    pub angular_velocity: Option<AngularSpec>,
    /// Vertex sets with prescribed motion.
    #[serde(default)]
    pub prescribed: Vec<PrescribedSpec>,
}

/// An MPM region.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Axis-aligned box `[min, max]` (before `transform`).
    Box {
        /// Lower corner.
        min: Vec<f64>,
        /// Upper corner.
        max: Vec<f64>,
        /// Optional placement.
        #[serde(default)]
        transform: Option<TransformSpec>,
    },
    /// Disk (2D) or ball (3D).
    Disk {
        /// Centre.
        center: Vec<f64>,
        /// Radius.
        radius: f64,
        /// How particles are placed (2D `polar` gives a smooth circular boundary).
        #[serde(default)]
        sampling: Sampling,
    },
    /// Annulus (2D).
    Ring {
        /// Centre.
        center: Vec<f64>,
        /// Inner radius.
        r_in: f64,
        /// Outer radius.
        r_out: f64,
        /// How particles are placed.
        #[serde(default)]
        sampling: Sampling,
    },
    /// Upper half annulus (2D).
    SemicircularRing {
        /// Centre.
        center: Vec<f64>,
        /// Inner radius.
        r_in: f64,
        /// Outer radius.
        r_out: f64,
    },
    /// The inside of a mesh file's cells: `{ "file": { "path": "body.msh" } }` (or
    /// `{ "file": "body.msh" }`), as a FEM body's mesh file.
    File(MeshFile),
    /// The spelling of a mesh-file shape before it was the same as a FEM body's: never read
    /// (its deserialiser refuses it with the spelling to use).
    Mesh(OldMeshShape),
}

/// `{ "mesh": { "file": … } }`, the old spelling of an MPM body's mesh-file shape: no value
/// has this type; reading one is the error that names the spelling to use.
#[derive(Debug, Clone)]
pub enum OldMeshShape {}

impl Serialize for OldMeshShape {
    fn serialize<S: serde::Serializer>(&self, _: S) -> Result<S::Ok, S::Error> {
        match *self {}
    }
}

impl<'de> Deserialize<'de> for OldMeshShape {
    fn deserialize<D: serde::Deserializer<'de>>(de: D) -> Result<Self, D::Error> {
        let v = serde_json::Value::deserialize(de)?;
        let path = v.get("file").and_then(|f| f.as_str()).unwrap_or("body.msh");
        Err(serde::de::Error::custom(format!(
            "the old spelling of a mesh file: write `\"shape\": {{ \"file\": {{ \"path\": \
             \"{path}\" }} }}` (or `{{ \"file\": \"{path}\" }}`), as a FEM body's `\"mesh\"`"
        )))
    }
}

/// A Gmsh `.msh` file (path relative to the scene file), for an MPM body's shape or a FEM body's
/// mesh alike: `{ "path": "body.msh", "reorient": true }`, or just `"body.msh"`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct MeshFile {
    /// Path.
    pub path: String,
    /// Flip every cell of a mesh whose cells are all inverted (else such a file is an error; a
    /// mesh of mixed orientation is an error either way).
    #[serde(default, skip_serializing_if = "is_false")]
    pub reorient: bool,
}

impl MeshFile {
    /// The file `path`, its cells as they are.
    pub fn new(path: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            reorient: false,
        }
    }
}

impl<'de> Deserialize<'de> for MeshFile {
    fn deserialize<D: serde::Deserializer<'de>>(de: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Full {
            path: String,
            #[serde(default)]
            reorient: bool,
        }
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = MeshFile;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a mesh file: { \"path\": \"body.msh\" } or \"body.msh\"")
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<MeshFile, E> {
                Ok(MeshFile::new(s))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, m: A) -> Result<MeshFile, A::Error> {
                let f = Full::deserialize(serde::de::value::MapAccessDeserializer::new(m))?;
                Ok(MeshFile {
                    path: f.path,
                    reorient: f.reorient,
                })
            }
        }
        de.deserialize_any(V)
    }
}

/// Particle placement in round shapes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampling {
    /// The regular sub-grid of the background grid (`particles_per_cell`): the boundary is a
    /// staircase at the particle spacing.
    #[default]
    Lattice,
    /// Concentric circles at the same spacing, each with equally spaced particles (2D): the
    /// boundary is a circle — for contact measurements such as the Hertz test.
    Polar,
}

/// A FEM mesh.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum MeshSpec {
    /// Rectangle with `cells = [nx, ny]`.
    Rectangle {
        /// Lower corner.
        min: Vec<f64>,
        /// Upper corner.
        max: Vec<f64>,
        /// Cells per axis.
        cells: Vec<usize>,
    },
    /// Box with `cells = [nx, ny, nz]`.
    Cuboid {
        /// Lower corner.
        min: Vec<f64>,
        /// Upper corner.
        max: Vec<f64>,
        /// Cells per axis.
        cells: Vec<usize>,
    },
    /// Disk with `rings` rings.
    Disk {
        /// Centre.
        center: Vec<f64>,
        /// Radius.
        radius: f64,
        /// Rings.
        rings: usize,
    },
    /// Annulus with `cells = [n_r, n_theta]`.
    Ring {
        /// Centre.
        center: Vec<f64>,
        /// Inner radius.
        r_in: f64,
        /// Outer radius.
        r_out: f64,
        /// Cells across and around.
        cells: Vec<usize>,
    },
    /// Upper half annulus with `cells = [n_r, n_theta]`.
    SemicircularRing {
        /// Centre.
        center: Vec<f64>,
        /// Inner radius.
        r_in: f64,
        /// Outer radius.
        r_out: f64,
        /// Cells across and along.
        cells: Vec<usize>,
    },
    /// Band of thickness `thickness` along `y = offset + amplitude cos(2π x / wavelength)` for
    /// `x ∈ [x0, x1]` (negative thickness: below the curve).
    CosineStrip {
        /// Amplitude (m).
        amplitude: f64,
        /// Wavelength (m).
        wavelength: f64,
        /// Mean height (m).
        offset: f64,
        /// Start of the x range.
        x0: f64,
        /// End of the x range.
        x1: f64,
        /// Thickness (signed).
        thickness: f64,
        /// Cells along and across.
        cells: Vec<usize>,
    },
    /// A Gmsh `.msh` file (path relative to the scene file): `{ "file": { "path": "body.msh" } }`
    /// or `{ "file": "body.msh" }`, as an MPM body's mesh-file shape.
    File(MeshFile),
}

/// Vertices with prescribed motion.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PrescribedSpec {
    /// Which vertices.
    pub vertices: VertexSelector,
    /// Piecewise-constant rigid velocities; after the last segment the vertices stay put.
    pub motion: Vec<MotionSegment>,
}

/// A vertex set.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum VertexSelector {
    /// Every vertex (the body becomes a moving boundary, BFEMP §4.4).
    All,
    /// Vertices with coordinate `axis` below `value`.
    Below {
        /// Axis (0 = x).
        axis: usize,
        /// Threshold.
        value: f64,
    },
    /// Vertices with coordinate `axis` above `value`.
    Above {
        /// Axis.
        axis: usize,
        /// Threshold.
        value: f64,
    },
    /// Explicit vertex indices.
    List(Vec<usize>),
}

/// One segment of a motion script.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSegment {
    /// End time of the segment (s).
    pub until: f64,
    /// Linear velocity (m/s).
    #[serde(default)]
    pub velocity: Option<Vec<f64>>,
    /// Angular velocity (rad/s; scalar in 2D, vector in 3D).
    #[serde(default)]
    pub angular_velocity: Option<AngularSpec>,
    /// Rotation centre at the start of the segment (default: centroid of the set at t = 0,
    /// carried along by the translation).
    #[serde(default)]
    pub center: Option<Vec<f64>>,
}

/// Contact settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Activation distance d̂ (m).
    pub dhat: f64,
    /// Barrier stiffness κ (Pa).
    pub kappa: f64,
    /// Coulomb friction coefficient μ (default 0).
    #[serde(default)]
    pub friction: f64,
    /// Static friction velocity threshold ε_v (m/s, default 1e-3).
    #[serde(default = "default_eps_v")]
    pub eps_v: f64,
    /// The barrier's Hessian in Newton: `"projected"` (default) or `"gauss_newton"`.
    #[serde(default)]
    pub hessian: BarrierHessianSpec,
    /// Per-pair overrides.
    #[serde(default)]
    pub pairs: Vec<PairSpec>,
}

/// The barrier's Hessian approximation (femp-contact's `BarrierHessian`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BarrierHessianSpec {
    /// The exact Hessian with negative eigenvalues clipped per term (the IPC default).
    #[default]
    Projected,
    /// `ω b''(d) ∇d∇dᵀ`: PSD by construction; fewer Newton iterations while particles slide
    /// along stiff facets, less robust where they switch features (see femp-contact).
    GaussNewton,
}

fn default_eps_v() -> f64 {
    1e-3
}

/// Overrides for one pair of bodies.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PairSpec {
    /// The two body names.
    pub bodies: [String; 2],
    /// Whether the pair interacts at all (default true).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// d̂ override.
    #[serde(default)]
    pub dhat: Option<f64>,
    /// κ override.
    #[serde(default)]
    pub kappa: Option<f64>,
    /// μ override.
    #[serde(default)]
    pub friction: Option<f64>,
    /// ε_v override.
    #[serde(default)]
    pub eps_v: Option<f64>,
}

fn yes() -> bool {
    true
}

/// A level-set boundary on the MPM grid.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// Geometry: the solid side is where the level set is negative.
    pub shape: BoundaryShape,
    /// No-slip (grid velocity = boundary velocity) or slip (zero normal relative velocity).
    pub condition: BoundaryCondition,
    /// Optional motion of the boundary (same script as prescribed vertices; translation only).
    #[serde(default)]
    pub motion: Vec<MotionSegment>,
}

/// Level-set geometry.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum BoundaryShape {
    /// The half-space behind a plane: solid where `(x − point)·normal < 0`.
    HalfPlane {
        /// A point on the plane.
        point: Vec<f64>,
        /// Normal pointing into the free region.
        normal: Vec<f64>,
    },
    /// 2D: solid above (`solid_above = true`) or below the curve
    /// `y = offset + amplitude cos(2π x / wavelength)`.
    Cosine {
        /// Amplitude.
        amplitude: f64,
        /// Wavelength.
        wavelength: f64,
        /// Mean height.
        offset: f64,
        /// Which side is solid.
        solid_above: bool,
    },
}

/// Boundary condition on grid nodes inside a level set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryCondition {
    /// Node velocity = boundary velocity.
    NoSlip,
    /// Normal component of the relative velocity = 0.
    Slip,
}

// Constructors for scenes built in code: the required fields as arguments, every other field
// as a scene file without it reads (tested against parsing such a file).

impl SceneSpec {
    /// A `dimension`-D BFEMP scene of `time`, with no bodies yet, no gravity and the default
    /// solver.
    pub fn new(dimension: usize, time: TimeSpec) -> Self {
        Self {
            name: None,
            dimension,
            method: Method::default(),
            gravity: None,
            time,
            solver: SolverSpec::default(),
            mpm: None,
            bodies: Vec::new(),
            contact: None,
            boundaries: Vec::new(),
            augury: None,
        }
    }
}

impl TimeSpec {
    /// Steps of `dt` for `duration` seconds, backward Euler, a frame every step.
    pub fn new(dt: f64, duration: f64) -> Self {
        Self {
            dt,
            duration,
            integrator: IntegratorSpec::default(),
            frame_interval: None,
        }
    }
}

impl MpmSpec {
    /// A grid of spacing `grid_spacing` with the default (APIC) transfer.
    pub fn new(grid_spacing: f64) -> Self {
        Self {
            grid_spacing,
            transfer: TransferSpec::default(),
            flip_ratio: one(),
        }
    }
}

impl MaterialSpec {
    /// The default model (neo-Hookean) with Young's modulus `e`, Poisson's ratio `nu` and
    /// density `rho`.
    pub fn new(e: f64, nu: f64, rho: f64) -> Self {
        Self {
            model: ModelSpec::default(),
            youngs_modulus: e,
            nu,
            rho,
        }
    }
}

impl MpmBody {
    /// Particles filling `shape`, at rest, with the default particles per cell.
    pub fn new(name: impl Into<String>, shape: ShapeSpec, material: MaterialSpec) -> Self {
        Self {
            name: name.into(),
            shape,
            particles_per_cell: None,
            material,
            velocity: None,
            angular_velocity: None,
        }
    }
}

impl FemBody {
    /// `mesh` where it is, at rest, free.
    pub fn new(name: impl Into<String>, mesh: MeshSpec, material: MaterialSpec) -> Self {
        Self {
            name: name.into(),
            mesh,
            transform: None,
            material,
            velocity: None,
            angular_velocity: None,
            prescribed: Vec::new(),
        }
    }
}

impl ContactSpec {
    /// Barrier contact with activation distance `dhat` and stiffness `kappa`, frictionless.
    pub fn new(dhat: f64, kappa: f64) -> Self {
        Self {
            dhat,
            kappa,
            friction: 0.0,
            eps_v: default_eps_v(),
            hessian: BarrierHessianSpec::default(),
            pairs: Vec::new(),
        }
    }
}

impl PairSpec {
    /// No override yet for the pair of bodies `a` and `b`.
    pub fn new(a: impl Into<String>, b: impl Into<String>) -> Self {
        Self {
            bodies: [a.into(), b.into()],
            enabled: yes(),
            dhat: None,
            kappa: None,
            friction: None,
            eps_v: None,
        }
    }
}

impl MotionSegment {
    /// Until `until`, no motion (overwrite `velocity` or `angular_velocity` to move).
    pub fn until(until: f64) -> Self {
        Self {
            until,
            velocity: None,
            angular_velocity: None,
            center: None,
        }
    }
}

impl Default for AugurySpec {
    fn default() -> Self {
        Self {
            grid_spacing: None,
            grid_ratio: None,
            kernel: KernelSpec::default(),
            transfer: AuguryTransferSpec::default(),
            tau: None,
            iterations: one_usize(),
            model: AuguryModelSpec::default(),
            friction: 0.0,
            contact: AuguryContactSpec::default(),
            penalty: None,
            obstacles: AuguryObstaclesSpec::default(),
            penetration_limit: half(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read<T: serde::de::DeserializeOwned>(json: &str) -> T {
        serde_json::from_str(json).unwrap()
    }

    /// Aitken's relaxation of the friction loop is on by default, off where the scene chooses
    /// the lags otherwise or turns it off; explicitly on with another choice is refused by
    /// validation (bad_input).
    #[test]
    fn aitken_is_the_default_unless_the_lags_are_chosen_otherwise() {
        let on = |json: &str| read::<SolverSpec>(json).aitken(2);
        assert!(on("{}"));
        assert!(on(r#"{"friction_aitken": true}"#));
        assert!(!on(r#"{"friction_aitken": false}"#));
        assert!(!on(r#"{"friction_relaxation": true}"#));
        assert!(!on(r#"{"friction_extrapolation": true}"#));
        assert!(!on(r#"{"friction_anderson": 3}"#));
        assert!(on(r#"{"friction_anderson": 0}"#));
        assert!(!on(
            r#"{"friction_relaxation": true, "friction_aitken": false}"#
        ));
    }

    /// Anderson acceleration of the friction loop by default in 3D only (3 past iterates), off
    /// where the scene chooses the lags otherwise, a value set used in either dimension; with
    /// it on, Aitken's factor is off unless set (and then validation refuses the pair).
    #[test]
    fn friction_anderson_defaults_by_dimension_unless_the_lags_are_chosen_otherwise() {
        let depth = |json: &str, d: usize| read::<SolverSpec>(json).anderson(d);
        assert_eq!(depth("{}", 3), SolverSpec::AUTO_ANDERSON_3D);
        assert_eq!(depth("{}", 2), 0);
        assert_eq!(depth(r#"{"friction_anderson": 0}"#, 3), 0);
        assert_eq!(depth(r#"{"friction_anderson": 5}"#, 2), 5);
        for other in [
            r#"{"friction_aitken": true}"#,
            r#"{"friction_relaxation": true}"#,
            r#"{"friction_extrapolation": true}"#,
        ] {
            assert_eq!(depth(other, 3), 0, "{other}");
        }
        assert_eq!(depth(r#"{"friction_aitken": false}"#, 3), 3);
        let aitken = |json: &str, d: usize| read::<SolverSpec>(json).aitken(d);
        assert!(!aitken("{}", 3));
        assert!(aitken("{}", 2));
        assert!(aitken(r#"{"friction_anderson": 0}"#, 3));
        assert!(aitken(r#"{"friction_aitken": true}"#, 3));
        // Resolved, a 3D scene records the depth it ran with; the scene itself stays as written.
        let spec = read::<SolverSpec>("{}");
        assert_eq!(spec.resolved(3).friction_anderson, Some(3));
        assert_eq!(spec.resolved(3).friction_aitken, Some(false));
        assert!(!serde_json::to_string(&spec).unwrap().contains("anderson"));
    }

    /// Inexact friction solves by default in 3D only (η = 0.3), a value set used in either,
    /// and a scene that leaves the field out writes it out again (its copy in a run's outputs,
    /// its checkpoints) as absent, not as one dimension's value.
    #[test]
    fn friction_forcing_defaults_by_dimension_and_a_set_value_holds() {
        let forcing = |json: &str, d: usize| read::<SolverSpec>(json).forcing(d);
        assert_eq!(forcing("{}", 3), 0.3);
        assert_eq!(forcing("{}", 2), 0.0);
        assert_eq!(forcing(r#"{"friction_forcing": 0}"#, 3), 0.0);
        assert_eq!(forcing(r#"{"friction_forcing": 0.5}"#, 2), 0.5);
        let written = serde_json::to_value(read::<SolverSpec>("{}")).unwrap();
        assert!(written.get("friction_forcing").is_none(), "{written}");
    }

    /// `friction_update_later` left out is on in 3D and off in 2D; a set value holds in
    /// either, and a default is written as absent (a scene copy says what its file said).
    #[test]
    fn friction_update_later_defaults_by_dimension_and_a_set_value_holds() {
        let later = |json: &str, d: usize| read::<SolverSpec>(json).update_later(d);
        assert!(later("{}", 3) && !later("{}", 2));
        assert!(!later(r#"{"friction_update_later": false}"#, 3));
        assert!(later(r#"{"friction_update_later": true}"#, 2));
        let written = serde_json::to_value(read::<SolverSpec>("{}")).unwrap();
        assert!(written.get("friction_update_later").is_none(), "{written}");
    }

    /// Each constructor's defaults are those of a scene file that leaves the fields out.
    #[test]
    fn constructors_default_as_a_scene_file_does() {
        let same = |a: &dyn std::fmt::Debug, b: &dyn std::fmt::Debug| {
            assert_eq!(format!("{a:?}"), format!("{b:?}"))
        };
        same(
            &SceneSpec::new(2, TimeSpec::new(0.1, 1.0)),
            &read::<SceneSpec>(
                r#"{"dimension": 2, "time": {"dt": 0.1, "duration": 1.0}, "bodies": []}"#,
            ),
        );
        same(
            &MpmSpec::new(0.5),
            &read::<MpmSpec>(r#"{"grid_spacing": 0.5}"#),
        );
        same(
            &MaterialSpec::new(1e6, 0.3, 1e3),
            &read::<MaterialSpec>(r#"{"E": 1e6, "nu": 0.3, "rho": 1e3}"#),
        );
        let shape = || ShapeSpec::Box {
            min: vec![0.0, 0.0],
            max: vec![1.0, 1.0],
            transform: None,
        };
        same(
            &MpmBody::new("a", shape(), MaterialSpec::new(1.0, 0.3, 1.0)),
            &read::<MpmBody>(
                r#"{"name": "a", "shape": {"box": {"min": [0, 0], "max": [1, 1]}},
                    "material": {"E": 1, "nu": 0.3, "rho": 1}}"#,
            ),
        );
        let mesh = || MeshSpec::Rectangle {
            min: vec![0.0, 0.0],
            max: vec![1.0, 1.0],
            cells: vec![2, 2],
        };
        same(
            &FemBody::new("b", mesh(), MaterialSpec::new(1.0, 0.3, 1.0)),
            &read::<FemBody>(
                r#"{"name": "b", "mesh": {"rectangle": {"min": [0, 0], "max": [1, 1],
                    "cells": [2, 2]}}, "material": {"E": 1, "nu": 0.3, "rho": 1}}"#,
            ),
        );
        same(
            &ContactSpec::new(1e-3, 1e5),
            &read::<ContactSpec>(r#"{"dhat": 1e-3, "kappa": 1e5}"#),
        );
        same(
            &PairSpec::new("a", "b"),
            &read::<PairSpec>(r#"{"bodies": ["a", "b"]}"#),
        );
        same(
            &MotionSegment::until(2.0),
            &read::<MotionSegment>(r#"{"until": 2.0}"#),
        );
        same(&AugurySpec::default(), &read::<AugurySpec>("{}"));
    }
}
