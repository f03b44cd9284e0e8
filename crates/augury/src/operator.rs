//! The grid-transfer operator `H` on generalised velocity fields `V = {v, B}` (eqs. 10–22).

use femp_kernels::{Grid, Kernel, Stencils, transfer};
use nalgebra::{SMatrix, SVector, Vector3};

use crate::error::{AuguryError, check_len};

/// Which transfer `H` is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransferKind {
    /// PIC (eqs. 10–12): `B` is ignored and returned as zero; conserves linear momentum.
    Pic,
    /// APIC (eqs. 17–20): conserves linear and angular momentum, reproduces affine fields.
    Apic,
}

/// `H` for one configuration of particles: build with [`Transfer::new`], place with
/// [`Transfer::set_positions`], apply with [`Transfer::apply`] (buffers are reused).
pub struct Transfer<const D: usize> {
    grid: Grid<D>,
    kind: TransferKind,
    stencils: Option<Stencils<D>>,
    grid_mass: Vec<f64>,
    grid_velocity: Vec<SVector<f64, D>>,
}

impl<const D: usize> Transfer<D> {
    /// A transfer on a background grid of spacing `h` (origin at 0) with the given B-spline.
    pub fn new(h: f64, kernel: Kernel, kind: TransferKind) -> Result<Self, AuguryError> {
        Ok(Self {
            grid: Grid::new(h, SVector::zeros(), kernel)?,
            kind,
            stencils: None,
            grid_mass: Vec::new(),
            grid_velocity: Vec::new(),
        })
    }

    /// The kind of transfer.
    pub fn kind(&self) -> TransferKind {
        self.kind
    }

    /// The background grid.
    pub fn grid(&self) -> &Grid<D> {
        &self.grid
    }

    /// `D_p` (the scalar `c h²` with `D_p = c h² I`).
    pub fn d_p(&self) -> f64 {
        self.grid.d_p()
    }

    /// Set the particle positions `H` depends on.
    pub fn set_positions(&mut self, x: &[SVector<f64, D>]) -> Result<(), AuguryError> {
        match &mut self.stencils {
            Some(st) => st.rebuild(x)?,
            None => self.stencils = Some(self.grid.stencils(x)?),
        }
        Ok(())
    }

    /// `(v_out, b_out) = H (v, b)` with particle masses `mass`.
    pub fn apply(
        &mut self,
        mass: &[f64],
        v: &[SVector<f64, D>],
        b: &[SMatrix<f64, D, D>],
        v_out: &mut [SVector<f64, D>],
        b_out: &mut [SMatrix<f64, D, D>],
    ) -> Result<(), AuguryError> {
        let st = self
            .stencils
            .as_ref()
            .expect("Transfer::set_positions must be called before apply");
        let n = st.num_particles();
        check_len("particle masses", n, mass.len())?;
        check_len("particle velocities", n, v.len())?;
        check_len("output velocities", n, v_out.len())?;
        check_len("output B", n, b_out.len())?;
        self.grid_mass.resize(st.num_nodes(), 0.0);
        self.grid_velocity.resize(st.num_nodes(), SVector::zeros());
        match self.kind {
            TransferKind::Pic => {
                transfer::p2g_pic(st, mass, v, &mut self.grid_mass, &mut self.grid_velocity)?;
                transfer::normalise(&self.grid_mass, &mut self.grid_velocity)?;
                transfer::g2p_pic(st, &self.grid_velocity, v_out)?;
                b_out.iter_mut().for_each(|x| *x = SMatrix::zeros());
            }
            TransferKind::Apic => {
                check_len("particle B", n, b.len())?;
                transfer::p2g_apic(st, mass, v, b, &mut self.grid_mass, &mut self.grid_velocity)?;
                transfer::normalise(&self.grid_mass, &mut self.grid_velocity)?;
                transfer::g2p_apic(st, &self.grid_velocity, None, v_out, b_out)?;
            }
        }
        Ok(())
    }
}

/// `Σ m_p v_p`.
pub fn linear_momentum<const D: usize>(mass: &[f64], v: &[SVector<f64, D>]) -> SVector<f64, D> {
    mass.iter().zip(v).map(|(m, v)| v * *m).sum()
}

/// Angular momentum about the origin of a generalised field (z only in 2D):
/// `Σ m_p (x_p × v_p + ε : B_pᵀ)` — the APIC definition (the `B` term is what the affine modes
/// carry); pass `b = None` for plain particles.
pub fn angular_momentum<const D: usize>(
    mass: &[f64],
    x: &[SVector<f64, D>],
    v: &[SVector<f64, D>],
    b: Option<&[SMatrix<f64, D, D>]>,
) -> Vector3<f64> {
    let mut l = Vector3::zeros();
    for p in 0..mass.len() {
        let (xp, vp) = (x[p], v[p]);
        let (x3, v3) = (lift(&xp), lift(&vp));
        l += x3.cross(&v3) * mass[p];
        if let Some(b) = b {
            l += transfer::apic_spin(&b[p]) * mass[p];
        }
    }
    l
}

fn lift<const D: usize>(v: &SVector<f64, D>) -> Vector3<f64> {
    Vector3::new(v[0], v[1], if D == 3 { v[D - 1] } else { 0.0 })
}
