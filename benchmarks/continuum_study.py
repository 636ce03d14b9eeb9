"""3D continuum reference study: the paper's mesh against a locking-free continuum.

Reproduces the planning study docs/mesh_locking_study.md (variant B: bottom face clamped, top face
held transversely and tied axially as a rigid plate sliding along the axis) with
fe.continuum, and prints Markdown tables:

1. nu = 0: the continuum equals the Euler-Bernoulli beam;
2. convergence of the locking-free continuum (quadratic hexahedra) and why it
   sits slightly above the beam (Poisson restraint at the clamped faces);
3. the paper's mesh (linear hexahedra 300 x 8 x 4, SRI; and fully integrated):
   f1 unloaded / at 74 N, buckling load, load for 37 Hz, effective bending factor;
4. locking: refinement along the length (300 / 600 / 1200), the width and the layers;
5. the beam with the measured factor against the paper's mesh.

    python benchmarks/continuum_study.py            # about 2.5 minutes, ~3 GB of memory
    python benchmarks/continuum_study.py --finest   # adds Hex2 300x12x2 graded: +2 min, ~8 GB
    python benchmarks/continuum_study.py --quick    # about 1 minute, skips the larger meshes
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.optimize

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine  # noqa: E402

import fe  # noqa: E402
import fe.continuum as fc  # noqa: E402

RIG = fe.Rig()
P74 = 74.0
F37 = 37.0


def graded(nx, ny, nz, strength=0.75, rig=RIG):
    """Mesh refined toward the clamped ends and the free edges (node arrays, m)."""
    return (fc.graded_nodes(rig.length_m, nx, strength), fc.graded_nodes(rig.width_m, ny, strength), nz)


def figures(rig, mesh, element, loaded=True):
    """f0 [Hz], f74 [Hz], Pcr [N], P for 37 Hz [N], dofs, seconds."""
    t = time.perf_counter()
    f0 = fc.strip_modes(rig, mesh, element, 0.0)[0]
    pcr = fc.buckling_load(rig, mesh, element)
    f74 = fc.strip_modes(rig, mesh, element, P74)[0] if loaded else np.nan
    p37 = fc.load_for_frequency(rig, mesh, element, F37) if loaded else np.nan
    return dict(f0=f0, f74=f74, pcr=pcr, p37=p37, dofs=fc.n_dofs(rig, mesh, element), s=time.perf_counter() - t)


def beam_load_for_frequency(rig, factor, f_target=F37):
    pcr = 4 * np.pi**2 * rig.EI * factor / rig.length_m**2
    return scipy.optimize.brentq(lambda p: fc.beam_frequency(rig, p, factor) - f_target, 0.0, 0.999 * pcr, xtol=1e-6)


def label(mesh):
    nx, ny, nz = (m if np.ndim(m) == 0 else len(m) - 1 for m in mesh)
    return f"{nx}x{ny}x{nz}" + ("" if all(np.ndim(m) == 0 for m in mesh) else " graded")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="skip the larger meshes")
    ap.add_argument(
        "--finest", action="store_true", help="add the Hex2 300x12x2 graded mesh (225k dofs, ~8 GB of memory)"
    )
    args = ap.parse_args()
    t_start = time.perf_counter()
    print(f"machine: {machine()}\n")

    # ------------------------------------------------------------------ beam references
    beam = dict(
        f0=fc.beam_frequency(RIG, 0.0),
        f74=fc.beam_frequency(RIG, P74),
        pcr=fc._beam(RIG).buckling_load(),
        p37=beam_load_for_frequency(RIG, 1.0),
    )
    print(
        "Euler-Bernoulli reference: fe.BeamModel, 64 elements, E = 58 GPa "
        f"(closed form 4 pi^2 EI / L^2 = {RIG.euler_load:.3f} N)\n"
    )

    # ------------------------------------------------------------------ 1. nu = 0
    rig0 = fe.Rig(poisson_ratio=0.0)
    b0 = dict(f0=fc.beam_frequency(rig0, 0.0), f74=fc.beam_frequency(rig0, P74), pcr=fc._beam(rig0).buckling_load())
    print("## 1. nu = 0: the continuum is the Euler-Bernoulli beam\n")
    print("| model | dofs | f1(0) Hz | f1(74 N) Hz | Pcr N | max deviation |")
    print("|---|---|---|---|---|---|")
    print(f"| EB beam (64 el.) | - | {b0['f0']:.4f} | {b0['f74']:.4f} | {b0['pcr']:.4f} | - |")
    print(f"| EB closed form | - | - | - | {rig0.euler_load:.4f} | - |")
    for mesh in ((80, 2, 2), (80, 4, 2)):
        r = figures(rig0, mesh, "hex2", loaded=False)
        r["f74"] = fc.strip_modes(rig0, mesh, "hex2", P74)[0]
        dev = max(abs(r[k] / b0[k] - 1) for k in ("f0", "f74", "pcr"))
        print(
            f"| Hex2 {label(mesh)} | {r['dofs']} | {r['f0']:.4f} | {r['f74']:.4f} | {r['pcr']:.4f} "
            f"| {100 * dev:.4f} % |"
        )

    # ------------------------------------------------------------------ 2. convergence
    print("\n## 2. Locking-free continuum (Hex2, nu = 0.33): convergence\n")
    print("| mesh | dofs | f1(0) Hz | f1(74 N) Hz | Pcr N | P for 37 Hz N | f0 / EB | Pcr / EB | time s |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| EB beam | - | {beam['f0']:.3f} | {beam['f74']:.3f} | {beam['pcr']:.2f} | {beam['p37']:.2f} | 1 | 1 | - |")
    if args.quick:
        meshes = [(40, 2, 1), (80, 4, 2), (120, 6, 2), (160, 8, 2), graded(120, 6, 2)]
    else:
        meshes = [(40, 2, 1), (80, 4, 2), (120, 6, 2), (120, 6, 4), (160, 8, 2), graded(120, 6, 2), graded(200, 8, 2)]
    if args.finest:
        meshes.append(graded(300, 12, 2))
    cont = {}
    for mesh in meshes:
        r = cont[label(mesh)] = figures(RIG, mesh, "hex2")
        print(
            f"| {label(mesh)} | {r['dofs']} | {r['f0']:.4f} | {r['f74']:.4f} | {r['pcr']:.3f} "
            f"| {r['p37']:.2f} | {r['f0'] / beam['f0']:.4f} | {r['pcr'] / beam['pcr']:.4f} "
            f"| {r['s']:.1f} |"
        )
    # observed order on the uniform sequence 80x4x2, 120x6x2, 160x8x2 (h = 1/80, 1/120, 1/160)
    fu = np.array([cont[k]["pcr"] for k in ("80x4x2", "120x6x2", "160x8x2")])
    h = 1.0 / np.array([80.0, 120.0, 160.0])
    p = scipy.optimize.brentq(
        lambda q: (h[0] ** q - h[1] ** q) / (h[1] ** q - h[2] ** q) - (fu[0] - fu[1]) / (fu[1] - fu[2]), 0.2, 6.0
    )
    extrap = fu[2] - (fu[1] - fu[2]) * h[2] ** p / (h[1] ** p - h[2] ** p)
    best = cont[label(meshes[-1])]
    print(
        f"\nUniform meshes: observed order of Pcr {p:.2f}; extrapolated Pcr {extrap:.3f} N "
        f"(finest graded {best['pcr']:.3f} N)."
    )
    print(
        f"Converged continuum against EB: f0 {100 * (best['f0'] / beam['f0'] - 1):+.2f} %, "
        f"f74 {100 * (best['f74'] / beam['f74'] - 1):+.2f} %, "
        f"Pcr {100 * (best['pcr'] / beam['pcr'] - 1):+.2f} %; "
        f"E/(1 - nu^2) everywhere would give f0 {100 * ((1 - 0.33**2) ** -0.5 - 1):+.1f} %, "
        f"Pcr {100 * (1 / (1 - 0.33**2) - 1):+.1f} %."
    )
    print(
        "\nWhy it is above the beam: Poisson restraint at the clamped faces.  The bottom face is\n"
        "fixed and the top face holds u_y = u_z = 0, so the anticlastic (plate) curvature that a\n"
        "free strip takes in bending is suppressed near both ends, where the bending moment is\n"
        "largest; there the strip bends with up to E / (1 - nu^2).  Away from the ends the edges are\n"
        "free and it bends as a beam.  With nu = 0 (section 1) the difference vanishes; shear\n"
        "deformation and rotary inertia are of order (h / L)^2 ~ 2e-5.  The excess grows with nu:\n"
    )
    print("| nu | Pcr / EB - 1 (Hex2 120x6x2 graded) | nu^2 / (1 - nu^2) | ratio |")
    print("|---|---|---|---|")
    for nu in (0.1, 0.2, 0.33, 0.45):
        rn = fe.Rig(poisson_ratio=nu)
        ex = fc.buckling_load(rn, graded(120, 6, 2, rig=rn), "hex2") / rn.euler_load - 1
        print(f"| {nu} | {100 * ex:.3f} % | {nu**2 / (1 - nu**2):.4f} | {ex / (nu**2 / (1 - nu**2)):.4f} |")

    # ------------------------------------------------------------------ 3. paper mesh
    print("\n## 3. The paper's mesh (Hex1 300 x 8 x 4)\n")
    print(
        "| element | dofs | f1(0) Hz | f1(74 N) Hz | Pcr N | P for 37 Hz N | factor from f0 / Pcr / f74 "
        "(vs EB) | from f0 / Pcr (vs continuum) | time s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    paper = {}
    for el in ("hex1_sri", "hex1"):
        t = time.perf_counter()
        r = figures(RIG, fc.PAPER_MESH, el)
        bf = fc.effective_bending_factor(RIG, fc.PAPER_MESH, el, P74)
        paper[el] = (r, bf)
        print(
            f"| {el} | {r['dofs']} | {r['f0']:.3f} | {r['f74']:.3f} | {r['pcr']:.2f} | {r['p37']:.2f} "
            f"| {bf.from_unloaded:.4f} / {bf.from_buckling:.4f} / {bf.from_loaded:.4f} "
            f"| {(r['f0'] / best['f0']) ** 2:.4f} / {r['pcr'] / best['pcr']:.4f} "
            f"| {time.perf_counter() - t:.1f} |"
        )
    a = 0.5 * RIG.length_m / 300
    print(
        f"\nParasitic-shear estimate 1 + 2 a^2 / ((1 + nu) h^2), a = {1e3 * a:.3f} mm: "
        f"{fc.shear_locking_estimate(RIG, 2 * a):.4f}"
    )

    # ------------------------------------------------------------------ 4. locking
    print("\n## 4. Locking of the paper's element (SRI)\n")
    print("Along the length (8 x 4 cross-section):\n")
    print("| mesh | dofs | Pcr N | Pcr / continuum | estimate | Pcr / EB | time s |")
    print("|---|---|---|---|---|---|---|")
    nxs = (300, 600) if args.quick else (300, 600, 1200)
    r_eb = []
    for nx in nxs:
        t = time.perf_counter()
        pcr = fc.buckling_load(RIG, (nx, 8, 4), "hex1_sri")
        r_eb.append(pcr / RIG.euler_load)
        print(
            f"| {nx}x8x4 | {fc.n_dofs(RIG, (nx, 8, 4), 'hex1_sri')} | {pcr:.2f} | {pcr / best['pcr']:.4f} "
            f"| {fc.shear_locking_estimate(RIG, RIG.length_m / nx):.4f} | {r_eb[-1]:.4f} "
            f"| {time.perf_counter() - t:.1f} |"
        )
    a = 0.5 * RIG.length_m / np.array(nxs)
    est = fc.shear_locking_estimate(RIG, 2 * a[0]) - 1
    c2 = (r_eb[0] - r_eb[1]) / (a[0] ** 2 - a[1] ** 2)
    c0 = r_eb[1] - c2 * a[1] ** 2
    print(
        f"\nFit Pcr / EB = c0 + c2 a^2 to 300 and 600: c0 = {c0:.4f} (the cross-section mesh's own "
        f"stiffness; continuum {best['pcr'] / beam['pcr']:.4f}), c2 a^2 at 300 = {c2 * a[0] ** 2:.4f} "
        f"against the estimate {est:.4f} (ratio {c2 * a[0] ** 2 / est:.4f})."
    )
    if len(nxs) == 3:
        rate = (r_eb[0] - r_eb[1]) / (r_eb[1] - r_eb[2])
        print(
            f"Rate: (r300 - r600) / (r600 - r1200) = {rate:.3f} (4 for element length squared); "
            f"the fit predicts r1200 = {c0 + c2 * a[2] ** 2:.4f}, measured {r_eb[2]:.4f}."
        )

    print("\nCross-section of the paper's element at 300 elements along the length (Pcr / continuum):\n")
    print("| cross-section (width x layers) | SRI | full 2x2x2 |")
    print("|---|---|---|")
    sections = [(8, 2), (8, 4), (8, 8), (16, 4)]
    for ny, nz in sections:
        row = [fc.buckling_load(RIG, (300, ny, nz), el) / best["pcr"] for el in ("hex1_sri", "hex1")]
        print(f"| {ny} x {nz} | {row[0]:.4f} | {row[1]:.4f} |")
    print("\nProxy used in CI (2 x 4 cross-section, 75 / 150 / 300 along the length), Pcr / EB:\n")
    rp = np.array([fc.buckling_load(RIG, (n, 2, 4), "hex1_sri") for n in (75, 150, 300)]) / RIG.euler_load
    ap_ = 0.5 * RIG.length_m / np.array([75, 150, 300])
    c2p = (rp[1] - rp[2]) / (ap_[1] ** 2 - ap_[2] ** 2)
    print(
        f"{rp.round(4).tolist()}; rate {(rp[0] - rp[1]) / (rp[1] - rp[2]):.4f}; "
        f"c2 a^2 at 300 = {c2p * ap_[2] ** 2:.4f} against the estimate "
        f"{fc.shear_locking_estimate(RIG, 2 * ap_[2]) - 1:.4f}"
    )

    # ------------------------------------------------------------------ 5. beam with the factor
    print("\n## 5. The beam with the measured factor against the paper's mesh\n")
    print(
        "| factor from | beam f1(0) Hz | beam f1(74 N) Hz | mesh f1(74 N) Hz | deviation "
        "| beam P for 37 Hz N "
        "| mesh P for 37 Hz N |"
    )
    print("|---|---|---|---|---|---|---|")
    r, bf = paper["hex1_sri"]
    for name, c in (
        ("f0", bf.from_unloaded),
        ("Pcr", bf.from_buckling),
        ("f74", bf.from_loaded),
        ("1.24 (DESIGN)", 1.24),
        ("1.0 (no locking)", 1.0),
    ):
        fb = fc.beam_frequency(RIG, P74, c)
        print(
            f"| {name} = {c:.4f} | {fc.beam_frequency(RIG, 0.0, c):.3f} | {fb:.3f} | {r['f74']:.3f} "
            f"| {100 * (fb / r['f74'] - 1):+.2f} % | {beam_load_for_frequency(RIG, c):.2f} "
            f"| {r['p37']:.2f} |"
        )
    print(
        f"\nLocking-free models reach {F37} Hz at {beam['p37']:.1f} N (beam) and {best['p37']:.1f} N "
        f"(continuum); the paper's mesh at {r['p37']:.1f} N."
    )
    print(f"\ntotal time {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
