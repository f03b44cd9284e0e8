//! Prescribed rigid motion: a script of constant-velocity segments (translation and rotation
//! about a centre), evaluated as the rigid map `X ↦ R(t) X + c(t)` from initial positions.

use nalgebra::{Rotation3, SMatrix, SVector, Vector3};

use crate::scene::{AngularSpec, MotionSegment};

/// A rigid transform `x = R X + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid<const D: usize> {
    /// Rotation.
    pub r: SMatrix<f64, D, D>,
    /// Translation.
    pub t: SVector<f64, D>,
}

impl<const D: usize> Rigid<D> {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            r: SMatrix::identity(),
            t: SVector::zeros(),
        }
    }

    /// Apply to a point.
    pub fn apply(&self, x: &SVector<f64, D>) -> SVector<f64, D> {
        self.r * x + self.t
    }

    /// `other ∘ self` (first self, then other).
    pub fn then(&self, other: &Rigid<D>) -> Rigid<D> {
        Rigid {
            r: other.r * self.r,
            t: other.r * self.t + other.t,
        }
    }
}

/// Rotation matrix for angular velocity `w` over time `dt` (2D: `w[0]` about z).
pub fn rotation<const D: usize>(w: &[f64], dt: f64) -> SMatrix<f64, D, D> {
    let mut r = SMatrix::<f64, D, D>::identity();
    if D == 2 {
        let (s, c) = (w[0] * dt).sin_cos();
        r[(0, 0)] = c;
        r[(0, 1)] = -s;
        r[(1, 0)] = s;
        r[(1, 1)] = c;
    } else {
        let axis = Vector3::new(w[0], w[1], w[2]);
        let rot = Rotation3::new(axis * dt);
        for i in 0..3 {
            for j in 0..3 {
                r[(i, j)] = rot[(i, j)];
            }
        }
    }
    r
}

/// Angular velocity of a spec as a slice of 1 (2D) or 3 (3D) numbers.
pub fn angular_components(a: &Option<AngularSpec>, d: usize) -> Vec<f64> {
    match a {
        Some(AngularSpec::Scalar(w)) => vec![*w],
        Some(AngularSpec::Vector(v)) => v.clone(),
        None => vec![0.0; if d == 2 { 1 } else { 3 }],
    }
}

#[derive(Clone, Debug)]
struct Segment<const D: usize> {
    start: f64,
    end: f64,
    v: SVector<f64, D>,
    w: Vec<f64>,
    /// Rotation centre at the segment's start.
    centre: SVector<f64, D>,
    /// Accumulated transform at the segment's start.
    at_start: Rigid<D>,
}

/// A motion script.
#[derive(Clone, Debug)]
pub struct Motion<const D: usize> {
    segments: Vec<Segment<D>>,
}

impl<const D: usize> Motion<D> {
    /// From segments; `centroid` is the default rotation centre at t = 0 (carried along).
    pub fn new(segments: &[MotionSegment], centroid: SVector<f64, D>) -> Self {
        let mut out = Vec::new();
        let mut start = 0.0;
        let mut acc = Rigid::identity();
        for s in segments {
            let v = s
                .velocity
                .as_ref()
                .map_or_else(SVector::zeros, |v| SVector::from_column_slice(v));
            let w = angular_components(&s.angular_velocity, D);
            let centre = s
                .center
                .as_ref()
                .map_or_else(|| acc.apply(&centroid), |c| SVector::from_column_slice(c));
            let seg = Segment {
                start,
                end: s.until,
                v,
                w,
                centre,
                at_start: acc,
            };
            acc = acc.then(&seg.local(s.until - start));
            out.push(seg);
            start = s.until;
        }
        Self { segments: out }
    }

    /// Whether any segment moves (a non-zero velocity or angular velocity): a moving script does
    /// work on the bodies it drives.
    pub fn moves(&self) -> bool {
        self.segments
            .iter()
            .any(|s| s.v.iter().any(|&x| x != 0.0) || s.w.iter().any(|&x| x != 0.0))
    }

    /// The rigid map from initial positions to positions at time `t`.
    pub fn at(&self, t: f64) -> Rigid<D> {
        let Some(last) = self.segments.last() else {
            return Rigid::identity();
        };
        let seg = self.segments.iter().find(|s| t < s.end).unwrap_or(last);
        let tau = (t.min(seg.end) - seg.start).max(0.0);
        seg.at_start.then(&seg.local(tau))
    }

    /// Velocity at time `t` of the point that started at `x0`.
    pub fn velocity(&self, t: f64, x0: &SVector<f64, D>) -> SVector<f64, D> {
        let Some(seg) = self.segments.iter().find(|s| t >= s.start && t < s.end) else {
            return SVector::zeros();
        };
        let x = self.at(t).apply(x0);
        let c = seg.centre + seg.v * (t - seg.start);
        let r = x - c;
        let mut v = seg.v;
        if D == 2 {
            v[0] -= seg.w[0] * r[1];
            v[1] += seg.w[0] * r[0];
        } else {
            let w = Vector3::new(seg.w[0], seg.w[1], seg.w[2]);
            let rr = Vector3::new(r[0], r[1], r[D - 1]);
            let c = w.cross(&rr);
            v[0] += c[0];
            v[1] += c[1];
            v[D - 1] += c[2];
        }
        v
    }
}

impl<const D: usize> Segment<D> {
    /// Rigid motion within this segment after `tau` seconds: rotate about the (moving) centre,
    /// translate.
    fn local(&self, tau: f64) -> Rigid<D> {
        let r = rotation::<D>(&self.w, tau);
        // x ↦ R (x − c) + c + v τ
        Rigid {
            r,
            t: self.centre - r * self.centre + self.v * tau,
        }
    }
}
