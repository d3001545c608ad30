"""ferrofmm against fmm3dpy (pip install fmm3dpy) in one process, on one workload.

Usage: python side_by_side.py N EPS [EPS ...]

Uniform points in the unit cube, charges uniform in [-0.5, 0.5), potential
and gradient at the sources, float64; errors are relative L2 against a NumPy
direct sum on 1000 sampled targets (the same for both codes). Times are wall
seconds of the whole call (tree, operators, evaluation). The two codes run
in alternation, each twice; the better time is reported.
"""

import sys
import time

import numpy as np

import ferrofmm

try:
    import fmm3dpy
except ImportError:  # pragma: no cover
    fmm3dpy = None


def direct(x, q, idx):
    phi = np.empty(len(idx))
    g = np.empty((len(idx), 3))
    for s in range(0, len(idx), 20):
        d = x[idx[s : s + 20]][:, None, :] - x[None, :, :]
        r = np.sqrt((d * d).sum(-1))
        zero = r == 0
        r[zero] = 1.0
        k = 1.0 / (4 * np.pi * r)
        k[zero] = 0.0
        phi[s : s + 20] = k @ q
        g[s : s + 20] = -np.einsum("j,ij,ijc->ic", q, k / r**2, d)
    return phi, g


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def main():
    n = int(float(sys.argv[1]))
    epss = [float(e) for e in sys.argv[2:]] or [1e-3, 1e-6]
    rng = np.random.default_rng(0)
    x = rng.random((n, 3))
    q = rng.random(n) - 0.5
    idx = rng.choice(n, 1000, replace=False)
    phi, grad = direct(x, q, idx)
    print(f"N = {n}, uniform cube, charges U[-0.5, 0.5), potential + gradient, f64")
    print("| code | eps | seconds | potential error | gradient error | order |")
    print("|---|---|---|---|---|---|")
    for eps in epss:
        best = {}
        for _ in range(2):
            t = time.perf_counter()
            r = ferrofmm.laplace(x, q, eps=eps, gradient=True)
            s = time.perf_counter() - t
            if "ferrofmm" not in best or s < best["ferrofmm"][0]:
                best["ferrofmm"] = (s, rel(r.potential[idx], phi), rel(r.gradient[idx], grad), r.info["order"])
            if fmm3dpy is not None:
                t = time.perf_counter()
                o = fmm3dpy.lfmm3d(eps=eps, sources=x.T.copy(), charges=q, pg=2)
                s = time.perf_counter() - t
                # fmm3dpy 2.x: kernel 1/(4 pi r), gradient as (3, n)
                e = (s, rel(o.pot[idx], phi), rel(o.grad[:, idx].T, grad), "-")
                if "fmm3dpy" not in best or s < best["fmm3dpy"][0]:
                    best["fmm3dpy"] = e
        for code, (s, ep, eg, p) in best.items():
            print(f"| {code} | {eps:g} | {s:.2f} | {ep:.1e} | {eg:.1e} | {p} |")


if __name__ == "__main__":
    main()
