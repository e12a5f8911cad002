"""Quality of the output on the real-mesh corpus (tests/data/real): every mesh under an
identity lattice, a 45-degree twist and a 40-degree bend (5x5x5 quadratic B-spline around the
mesh, as `python3 -m smoothffd quality` makes it) at levels 1, 3 and 6, measured by
smoothffd.metrics.quality. Prints a markdown table (one row per mesh and lattice) for
docs/results.md; --json writes every measure.

    PYTHONPATH=python /usr/bin/python3 scripts/quality_corpus.py [--json OUT.json]
"""
import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORPUS = os.path.join(ROOT, "tests", "data", "real")
MESHES = ["cube", "uv_sphere", "cylinder", "torus", "suzanne", "suzanne_subsurf", "goblet",
          "figure", "rock"]
LATTICES = [("identity", None, 0.0), ("twist 45", "twist", 45.0), ("bend 40", "bend", 40.0)]
LEVELS = (1, 3, 6)


def corpus_lattice(mesh, mode=None, amount=0.0):
    """The quality command's default lattice: 5x5x5 quadratic B-spline around the mesh's
    bounding box (5% margin), identity or deformed about z."""
    from smoothffd import cli, lattice_json

    lo, hi = cli.padded_box(mesh.positions, 0.05)
    doc = cli.make_lattice_doc(lo, hi, (5, 5, 5), (2, 2, 2), "bspline", mode, amount, 2)
    return lattice_json.build_lattice(*lattice_json.parse_lattice(doc, "corpus"))


def measure(name, mode=None, amount=0.0, levels=LEVELS, device="cpu"):
    import smoothffd
    from smoothffd import io as objio
    from smoothffd import metrics

    mesh = objio.read_obj_mesh(os.path.join(CORPUS, name + ".obj"))
    lat = corpus_lattice(mesh, mode, amount)
    out = []
    for level in levels:
        d = smoothffd.Deformer(mesh, lat, level=level, device=device)
        res = d.deform()
        tin = mesh.corner_vertices[d.plan.input_triangles()[0]]
        out.append((level, metrics.quality(res, mesh, lat, input_triangles=tin)))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args()
    rows, dump = [], []
    for name in MESHES:
        for label, mode, amount in LATTICES:
            ms = measure(name, mode, amount)
            dump += [dict(mesh=name, lattice=label, level=L, **q._asdict()) for L, q in ms]
            q = dict(ms)
            vol = [x.volume_change for _, x in ms if x.volume_change is not None]
            rows.append(
                f"| {name} | {label} | {' / '.join(str(q[L].reversed) for L in LEVELS)} | "
                f"{q[6].tiny} | {min(x.min_angle for _, x in ms):.3g}° "
                f"({ms[0][1].input_min_angle:.3g}°) | {max(x.max_aspect for _, x in ms):.4g} | "
                f"{max(x.flat_deviation for _, x in ms):.2g} / "
                f"{max(x.flat_slide for _, x in ms):.2g} | "
                + (f"{vol[-1]:+.2g} |" if vol else "open |"))
            print(rows[-1], file=sys.stderr)
    print("| mesh | lattice | reversed L = 1 / 3 / 6 | tiny L = 6 | smallest angle (input) | "
          "largest aspect | flat: off the surface / whole distance | volume change L = 6 |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(dump, f, indent=1, default=float)


if __name__ == "__main__":
    sys.path.insert(0, os.path.join(ROOT, "python"))
    np.seterr(all="ignore")
    main()
