"""Quality of the output on the real-mesh corpus (tests/data/real): every mesh under an
identity lattice, a 45-degree twist and a 40-degree bend (5x5x5 quadratic B-spline around the
mesh, as `python3 -m smoothffd quality` makes it) at levels 1, 3 and 6, measured by
smoothffd.metrics.quality. Prints a markdown table (one row per mesh and lattice) for
docs/results.md (scripts/report.py puts it there); --json writes every measure.

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


def measure_all():
    """Every mesh, lattice and level: a list of dicts (mesh, lattice, level, Quality's fields)."""
    rows = []
    for name in MESHES:
        for label, mode, amount in LATTICES:
            rows += [dict(mesh=name, lattice=label, level=L, **q._asdict())
                     for L, q in measure(name, mode, amount)]
    return rows


def table(rows):
    """Markdown table of measure_all's rows, one line per mesh and lattice."""
    out = ["| mesh | lattice | reversed L = 1 / 3 / 6 | tiny L = 6 | smallest angle (input) | "
           "largest aspect | flat: off the surface / whole distance | volume change L = 6 |",
           "|---|---|---|---|---|---|---|---|"]
    groups = {}
    for r in rows:
        groups.setdefault((r["mesh"], r["lattice"]), {})[r["level"]] = r
    for (name, label), q in groups.items():
        ms = [q[L] for L in LEVELS]
        vol = q[LEVELS[-1]]["volume_change"]
        out.append(
            f"| {name} | {label} | {' / '.join(str(q[L]['reversed']) for L in LEVELS)} | "
            f"{q[LEVELS[-1]]['tiny']} | {min(x['min_angle'] for x in ms):.3g}° "
            f"({ms[0]['input_min_angle']:.3g}°) | {max(x['max_aspect'] for x in ms):.4g} | "
            f"{max(x['flat_deviation'] for x in ms):.2g} / {max(x['flat_slide'] for x in ms):.2g} | "
            + (f"{vol:+.2g} |" if vol is not None else "open |"))
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args()
    rows = measure_all()
    print(table(rows))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1, default=float)


if __name__ == "__main__":
    sys.path.insert(0, os.path.join(ROOT, "python"))
    np.seterr(all="ignore")
    main()
