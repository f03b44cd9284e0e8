"""The Taichi reference for `cargo bench -p femp-kernels --bench transfers` (issue 2).

The same work as the bench's `apic_transfer_{2,3}d/*/random/N` on the same machine: N particles
at uniform random positions (4 per cell in 2D, 8 in 3D, h = 0.01), random mass, velocity and B,
stored in random memory order; one "transfer" = clear a dense grid, APIC P2G of mass and
momentum (quadratic B-spline, D_p = h^2/4 I), normalise, APIC G2P of v and B. Taichi's CPU
backend, f64, timed after a warm-up with `ti.sync()`; median of the repetitions.

    python3 -m venv /tmp/ti && /tmp/ti/bin/pip install taichi==1.7.4 numpy
    /tmp/ti/bin/python crates/kernels/benches/taichi_reference.py          # 2D and 3D, 1 and 2 threads
    /tmp/ti/bin/python crates/kernels/benches/taichi_reference.py 2 1000000 1

Prints one line per case: `taichi D=2 n=1000000 threads=1: 12.3 ms median, 81.3 M/s`.
Not part of CI (Taichi is not a dependency of femp); the figures go into docs/performance.md.
"""

import statistics
import sys
import time

import numpy as np


def run(dim, n, threads, reps):
    import taichi as ti

    ti.init(arch=ti.cpu, default_fp=ti.f64, cpu_max_num_threads=threads, log_level=ti.WARN)
    h = 0.01
    ppc = 4.0 if dim == 2 else 8.0
    side = (n / ppc) ** (1.0 / dim) * h
    cells = int(side / h) + 4
    inv_h = 1.0 / h
    d_inv = 4.0 / (h * h)

    rng = np.random.default_rng(42)
    x = ti.Vector.field(dim, ti.f64, shape=n)
    m = ti.field(ti.f64, shape=n)
    v = ti.Vector.field(dim, ti.f64, shape=n)
    b = ti.Matrix.field(dim, dim, ti.f64, shape=n)
    x.from_numpy(rng.uniform(0.0, side, size=(n, dim)))
    m.from_numpy(rng.uniform(0.5, 1.5, size=n))
    v.from_numpy(rng.uniform(-1.0, 1.0, size=(n, dim)))
    b.from_numpy(rng.uniform(-0.01, 0.01, size=(n, dim, dim)))
    shape = (cells,) * dim
    gm = ti.field(ti.f64, shape=shape)
    gv = ti.Vector.field(dim, ti.f64, shape=shape)

    @ti.kernel
    def clear():
        for i in ti.grouped(gm):
            gm[i] = 0.0
            gv[i] = ti.Vector.zero(ti.f64, dim)

    @ti.kernel
    def p2g():
        for p in x:
            xp = x[p] * inv_h
            base = ti.cast(xp - 0.5, ti.i32)
            fx = xp - base
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
            affine = m[p] * d_inv * b[p]
            mv = m[p] * v[p]
            for off in ti.static(ti.grouped(ti.ndrange(*((3,) * dim)))):
                dpos = (off - fx) * h
                weight = 1.0
                for a in ti.static(range(dim)):
                    weight *= w[off[a]][a]
                gv[base + off] += weight * (mv + affine @ dpos)
                gm[base + off] += weight * m[p]

    @ti.kernel
    def normalise():
        for i in ti.grouped(gm):
            if gm[i] > 0.0:
                gv[i] /= gm[i]

    @ti.kernel
    def g2p():
        for p in x:
            xp = x[p] * inv_h
            base = ti.cast(xp - 0.5, ti.i32)
            fx = xp - base
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
            nv = ti.Vector.zero(ti.f64, dim)
            nb = ti.Matrix.zero(ti.f64, dim, dim)
            for off in ti.static(ti.grouped(ti.ndrange(*((3,) * dim)))):
                dpos = (off - fx) * h
                weight = 1.0
                for a in ti.static(range(dim)):
                    weight *= w[off[a]][a]
                g = gv[base + off]
                nv += weight * g
                nb += weight * g.outer_product(dpos)
            v[p] = nv
            b[p] = nb

    def transfer():
        clear()
        p2g()
        normalise()
        g2p()

    for _ in range(3):
        transfer()
    ti.sync()
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        transfer()
        ti.sync()
        times.append(time.perf_counter() - t)
    med = statistics.median(times)
    print(
        f"taichi D={dim} n={n} threads={threads}: {med * 1e3:.1f} ms median, "
        f"{n / med / 1e6:.2f} M/s",
        flush=True,
    )
    ti.reset()


def main():
    args = sys.argv[1:]
    if args:
        dim, n, threads = int(args[0]), int(args[1]), int(args[2])
        run(dim, n, threads, reps=20)
        return
    for dim in (2, 3):
        for threads in (1, 2):
            run(dim, 1_000_000, threads, reps=20)


if __name__ == "__main__":
    main()
