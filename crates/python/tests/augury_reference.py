"""A second, independent implementation of 2D augury contact, written from the augury paper's
equations with numpy alone — it does not import femp, and shares no code with femp-augury.

What it implements, by equation of the paper (the one whose abstract begins "An efficient and
momentum conserving algorithm for enforcing contact between solid bodies is proposed"):

* the background grid: the standard quadratic B-spline (3 nodes per axis, origin at 0) or the
  4-node variant of appendix B (eqs. 60-63, with 1/4 for all four weights: the extracted 1/8 of
  eq. 62 breaks the partition of unity, see femp-kernels' spline.rs);
* PIC transfers (eqs. 10-12) and APIC transfers (eqs. 17-20), with D_p evaluated as the sum of
  eq. 18 at each particle (not the closed form c h^2 femp uses);
* the correction A_hat = (H - I) V_bar / tau (eq. 29) on V_bar = V + tau A (eq. 27, B_dot = 0),
  with the augury iterations of eqs. 36-37 and the undesirable parts of eq. 38 (separation) or
  eqs. 42-46 (Coulomb friction, Delta B always undesirable);
* area-weighted outward vertex normals of the boundary faces (section 2.3);
* linear triangles with the compressible neo-Hookean energy
  psi = mu/2 (tr F^T F - 2) - mu ln J + lambda/2 (ln J)^2 and lumped masses rho V_e / 3;
* the explicit Newmark scheme of eq. 32. Where the paper is silent — which velocity V_t the
  prediction of eq. 27 starts from at step n + 1 — this uses the half-step velocity
  V^{n+1/2}, as femp does (docs/augury.md says why); fixed vertices keep their velocity,
  take no correction and enter the grid with their mass and velocity.

The point is a check of femp's augury code from outside: the same scene stepped by both must
agree to round-off (crates/python/tests/test_augury_reference.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Sequence

import numpy as np

KINEMATIC_MASS = 1e8


def axis_weights(q: np.ndarray, kernel: str):
    """Base node and weights of one axis for positions `q` in cell units."""
    if kernel == "quadratic":
        base = np.floor(q - 0.5)
        f = q - base
        w = np.stack([0.5 * (1.5 - f) ** 2, 0.75 - (f - 1.0) ** 2, 0.5 * (f - 0.5) ** 2], axis=1)
    elif kernel == "quadratic4":
        i = np.floor(q)  # eq. 60
        t = q - i
        a = (1.0 - t) ** 2  # eq. 63
        b = (1.0 + t) * (1.0 - t) + (2.0 - t) * t
        c = t * t
        w = np.stack([a / 4.0, (a + b) / 4.0, (b + c) / 4.0, c / 4.0], axis=1)  # eq. 62
        base = i - 1.0
    else:
        raise ValueError(f"unknown kernel {kernel!r}")
    return base.astype(np.int64), w


class Transfer:
    """H (PIC or APIC) for one configuration of particles (eqs. 10-12, 17-20)."""

    def __init__(self, h: float, kernel: str = "quadratic", apic: bool = True):
        self.h = float(h)
        self.kernel = kernel
        self.apic = apic

    def set_positions(self, x: np.ndarray) -> None:
        h = self.h
        bx, wx = axis_weights(x[:, 0] / h, self.kernel)
        by, wy = axis_weights(x[:, 1] / h, self.kernel)
        k = wx.shape[1]
        lo_x, lo_y = bx.min(), by.min()
        ny = by.max() - lo_y + k
        nx = bx.max() - lo_x + k
        off = np.arange(k)
        ix = bx[:, None] + off[None, :]  # (n, k) node indices per axis
        iy = by[:, None] + off[None, :]
        n = x.shape[0]
        self.index = ((ix[:, :, None] - lo_x) * ny + (iy[:, None, :] - lo_y)).reshape(n, k * k)
        self.w = (wx[:, :, None] * wy[:, None, :]).reshape(n, k * k)
        # x_i - x_p for every node of the stencil.
        dx = ix * h - x[:, 0:1]
        dy = iy * h - x[:, 1:2]
        self.dxi = np.stack(
            [np.broadcast_to(dx[:, :, None], (n, k, k)), np.broadcast_to(dy[:, None, :], (n, k, k))],
            axis=-1,
        ).reshape(n, k * k, 2)
        self.num_nodes = int(nx * ny)
        # D_p = sum_i N_i (x_i - x_p) (x) (x_i - x_p)  (eq. 18).
        self.d_p = np.einsum("pk,pki,pkj->pij", self.w, self.dxi, self.dxi)
        self.d_p_inv = np.linalg.inv(self.d_p)

    def apply(self, m: np.ndarray, v: np.ndarray, b: Optional[np.ndarray]):
        """(v_out, B_out) = H (v, B) with particle masses m."""
        wm = self.w * m[:, None]
        idx = self.index.ravel()
        gm = np.bincount(idx, wm.ravel(), minlength=self.num_nodes)
        if self.apic:
            # v_p + B_p D_p^-1 (x_i - x_p)  (eq. 17)
            c = np.einsum("pij,pjk->pik", b, self.d_p_inv)
            vel = v[:, None, :] + np.einsum("pij,pkj->pki", c, self.dxi)
        else:
            vel = np.broadcast_to(v[:, None, :], self.dxi.shape)
        mom = wm[:, :, None] * vel
        gp = np.stack(
            [np.bincount(idx, mom[:, :, d].ravel(), minlength=self.num_nodes) for d in range(2)],
            axis=1,
        )
        gv = np.zeros_like(gp)
        has = gm > 0.0
        gv[has] = gp[has] / gm[has, None]
        vi = gv[self.index]  # (n, k, 2)
        v_out = np.einsum("pk,pkd->pd", self.w, vi)  # eq. 12 / 19
        if self.apic:
            b_out = np.einsum("pk,pki,pkj->pij", self.w, vi, self.dxi)  # eq. 20
        else:
            b_out = np.zeros((v.shape[0], 2, 2))
        return v_out, b_out


def undesirable(model: str, mu: float, dv: np.ndarray, db: np.ndarray, n: np.ndarray):
    """The undesirable part W of a proposed change (eq. 38, or eqs. 42-46)."""
    dn = np.einsum("pd,pd->p", dv, n)
    constrained = np.any(n != 0.0, axis=1)
    away = (dn > 0.0) & constrained
    w = np.zeros_like(dv)
    wb = np.zeros_like(db)
    if model == "separation":
        w[away] = dv[away]
        wb[away] = db[away]
    elif model == "friction":
        toward = (~away) & constrained
        t = dv - n * dn[:, None]  # tangential change (eq. 42)
        tl = np.linalg.norm(t, axis=1)
        s = np.minimum(tl, -mu * dn)  # eq. 43
        scale = np.where(tl > 0.0, 1.0 - s / np.where(tl > 0.0, tl, 1.0), 1.0)
        w[toward] = t[toward] * scale[toward, None]  # eq. 44, dv.n <= 0
        w[away] = dv[away]  # eq. 44, dv.n > 0
        wb[constrained] = db[constrained]  # eq. 45
    elif model != "sticky":
        raise ValueError(f"unknown contact model {model!r}")
    return w, wb


@dataclass
class Body:
    """One linear-triangle neo-Hookean body."""

    name: str
    rest: np.ndarray  # (n, 2) rest positions (the reference shape)
    cells: np.ndarray  # (m, 3) counter-clockwise triangles
    x: np.ndarray  # (n, 2) current positions
    v: np.ndarray  # (n, 2) velocities
    youngs: float
    nu: float
    rho: float
    fixed: np.ndarray  # (n,) bool
    a: np.ndarray = field(init=False)

    def __post_init__(self):
        self.rest = np.asarray(self.rest, float)
        self.cells = np.asarray(self.cells, np.int64)
        self.x = np.array(self.x, float)
        self.v = np.array(self.v, float)
        self.fixed = np.asarray(self.fixed, bool)
        self.mu = self.youngs / (2.0 * (1.0 + self.nu))
        self.lam = self.youngs * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))
        c = self.cells
        dm = np.stack([self.rest[c[:, 1]] - self.rest[c[:, 0]], self.rest[c[:, 2]] - self.rest[c[:, 0]]], axis=-1)
        self.volume = 0.5 * np.linalg.det(dm)
        if np.any(self.volume <= 0.0):
            raise ValueError(f"body {self.name}: a triangle is not counter-clockwise")
        self.dm_inv = np.linalg.inv(dm)
        n = self.rest.shape[0]
        self.mass = np.bincount(c.ravel(), np.repeat(self.rho * self.volume / 3.0, 3), minlength=n)
        # Boundary edges: the ones only one triangle has, kept in that triangle's orientation.
        edges = np.concatenate([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]])
        key = np.sort(edges, axis=1)
        _, inverse, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        self.edges = edges[count[inverse.ravel()] == 1]
        self.boundary = np.unique(self.edges)
        self.a = np.zeros_like(self.x)

    def elastic_forces(self) -> np.ndarray:
        c = self.cells
        x = self.x
        ds = np.stack([x[c[:, 1]] - x[c[:, 0]], x[c[:, 2]] - x[c[:, 0]]], axis=-1)
        f = ds @ self.dm_inv
        j = np.linalg.det(f)
        if np.any(j <= 0.0):
            raise FloatingPointError(f"body {self.name}: an element inverted")
        f_inv_t = np.linalg.inv(f).transpose(0, 2, 1)
        p = self.mu * f + (self.lam * np.log(j) - self.mu)[:, None, None] * f_inv_t
        # Force on vertices 1, 2: -V P Dm^-T; vertex 0 takes minus their sum.
        hmat = -self.volume[:, None, None] * (p @ self.dm_inv.transpose(0, 2, 1))
        out = np.zeros_like(x)
        np.add.at(out, c[:, 1], hmat[:, :, 0])
        np.add.at(out, c[:, 2], hmat[:, :, 1])
        np.add.at(out, c[:, 0], -hmat[:, :, 0] - hmat[:, :, 1])
        return out

    def vertex_normals(self) -> np.ndarray:
        """Area-weighted outward unit normals of the boundary vertices (order of `boundary`)."""
        d = self.x[self.edges[:, 1]] - self.x[self.edges[:, 0]]
        fn = np.stack([d[:, 1], -d[:, 0]], axis=1)  # outward for counter-clockwise triangles
        acc = np.zeros_like(self.x)
        np.add.at(acc, self.edges[:, 0], fn)
        np.add.at(acc, self.edges[:, 1], fn)
        n = acc[self.boundary]
        length = np.linalg.norm(n, axis=1)
        n[length > 0] /= length[length > 0, None]
        return n

    def elastic_energy(self) -> float:
        c = self.cells
        ds = np.stack([self.x[c[:, 1]] - self.x[c[:, 0]], self.x[c[:, 2]] - self.x[c[:, 0]]], axis=-1)
        f = ds @ self.dm_inv
        j = np.linalg.det(f)
        lnj = np.log(j)
        psi = 0.5 * self.mu * (np.einsum("eij,eij->e", f, f) - 2.0) - self.mu * lnj + 0.5 * self.lam * lnj**2
        return float(np.sum(self.volume * psi))


class System:
    """Bodies stepped by eq. 32 with the augury correction of eqs. 27-46."""

    def __init__(
        self,
        bodies: Sequence[Body],
        dt: float,
        gravity: Sequence[float],
        grid_spacing: float,
        kernel: str = "quadratic",
        apic: bool = True,
        tau: Optional[float] = None,
        iterations: int = 1,
        model: str = "friction",
        friction: float = 0.0,
        obstacles: str = "lumped",
        contact: bool = True,
    ):
        self.bodies: List[Body] = list(bodies)
        self.dt = float(dt)
        self.gravity = np.asarray(gravity, float)
        self.transfer = Transfer(grid_spacing, kernel, apic)
        self.tau = float(dt if tau is None else tau)
        self.iterations = iterations
        self.model = model
        self.friction = friction
        self.obstacles = obstacles
        self.contact_on = contact
        self.time = 0.0
        n = sum(len(b.boundary) for b in self.bodies)
        self.b = np.zeros((n, 2, 2))
        self.bdot = np.zeros((n, 2, 2))
        self.started = False
        self.last_iterations = 0

    def set_rigid_b(self, omegas: Sequence[float]) -> None:
        """B_p = L D_p for each body's rigid rotation rate (the initial condition of section 2.1.2)."""
        x = np.concatenate([b.x[b.boundary] for b in self.bodies])
        self.transfer.set_positions(x)
        k = 0
        for body, w in zip(self.bodies, omegas):
            lmat = np.array([[0.0, -w], [w, 0.0]])
            for _ in body.boundary:
                self.b[k] = lmat @ self.transfer.d_p[k]
                k += 1

    def _kinematic(self, body: Body) -> bool:
        return self.obstacles == "kinematic" and bool(np.all(body.fixed))

    def mechanical(self) -> None:
        for body in self.bodies:
            f = body.elastic_forces()
            body.a = self.gravity[None, :] + f / body.mass[:, None]
            body.a[body.fixed] = 0.0

    def correction(self):
        """Delta V of eqs. 35-37: (dv, dB) for the predicted field, and the iterations used."""
        apic = self.transfer.apic
        x = np.concatenate([b.x[b.boundary] for b in self.bodies])
        m = np.concatenate(
            [b.mass[b.boundary] * (KINEMATIC_MASS if self._kinematic(b) else 1.0) for b in self.bodies]
        )
        n = np.concatenate([b.vertex_normals() for b in self.bodies])
        vbar = np.concatenate([b.v[b.boundary] + self.tau * b.a[b.boundary] for b in self.bodies])
        if not apic:
            self.b[:] = 0.0
        bbar = self.b.copy()  # B_dot = 0 mechanically (eq. 28)
        self.transfer.set_positions(x)
        hv, hb = self.transfer.apply(m, vbar, bbar)
        dv = hv - vbar
        db = hb - bbar if apic else np.zeros_like(bbar)
        iterations = 0 if self.model == "sticky" else self.iterations
        active = 0
        for _ in range(iterations):
            w, wb = undesirable(self.model, self.friction, dv, db, n)
            if not apic:
                wb[:] = 0.0
            if not (np.any(w != 0.0) or np.any(wb != 0.0)):
                break
            active += 1
            hv, hb = self.transfer.apply(m, w, wb)
            dv += hv - w
            if apic:
                db += hb - wb
        return dv, db, active

    def contact(self) -> None:
        if not self.contact_on:
            self.last_iterations = 0
            return
        dv, db, self.last_iterations = self.correction()
        a_hat = dv / self.tau
        self.bdot = db / self.tau
        k = 0
        for body in self.bodies:
            kinematic = self._kinematic(body)
            for v in body.boundary:
                if not body.fixed[v]:
                    body.a[v] += a_hat[k]
                elif kinematic:
                    self.bdot[k] = 0.0
                k += 1

    def step(self) -> None:
        dt = self.dt
        if not self.started:
            self.mechanical()
            self.contact()
            self.started = True
        for body in self.bodies:
            free = ~body.fixed
            body.v[free] += 0.5 * dt * body.a[free]
            body.x[free] += dt * body.v[free]
        self.b += 0.5 * dt * self.bdot
        self.mechanical()
        self.contact()
        for body in self.bodies:
            free = ~body.fixed
            body.v[free] += 0.5 * dt * body.a[free]
        self.b += 0.5 * dt * self.bdot
        self.time += dt

    def momentum(self) -> np.ndarray:
        return sum(np.einsum("p,pd->d", b.mass, b.v) for b in self.bodies)

    def angular_momentum(self) -> float:
        """z angular momentum about the origin, with the APIC term sum m_p (B_p^T)_{xy - yx}."""
        total = 0.0
        k = 0
        for body in self.bodies:
            total += float(np.sum(body.mass * (body.x[:, 0] * body.v[:, 1] - body.x[:, 1] * body.v[:, 0])))
            for v in body.boundary:
                bm = self.b[k]
                total += body.mass[v] * (bm[1, 0] - bm[0, 1])
                k += 1
        return total
