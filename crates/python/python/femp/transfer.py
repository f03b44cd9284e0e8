"""Particle–grid transfers on the quadratic B-spline grid (PIC and APIC; BFEMP Tables 1–3,
augury eqs. 10–20)::

    t = femp.transfer.Transfer(x, h=0.1)          # stencils of particles x (n x D)
    grid_mass, grid_momentum = t.p2g(mass, v, B)  # B: APIC matrices (n x D x D); omit for PIC
    v_new, B_new = t.g2p(grid_momentum / grid_mass[:, None])
    t.nodes, t.node_positions                     # which nodes, in the grid arrays' order
"""

from ._femp import Transfer

__all__ = ["Transfer"]
