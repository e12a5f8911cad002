"""Puts the demo renders side by side and prints the summary (plain Python with numpy and
matplotlib; no bpy).

    python3 blender_scenes/composite.py [--out out/demo] [--docs docs/images] [scene ...]

For each scene directory OUT/<scene>/ written by render_demo.py: OUT/<scene>.png, two rows of
four (Original / Lattice modifier / Lattice + Subsurf / Smooth FFD): the shaded renders, then
the close-ups (reflection lines or shaded). With --docs, also a downscaled copy into that folder for the
README (each well under 150 KB).
"""
import argparse
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
VARIANTS = ("original", "lattice", "lattice_subsurf", "smooth_ffd")
LABELS = {"original": "Original", "lattice": "Lattice modifier",
          "lattice_subsurf": "Lattice + Subsurf", "smooth_ffd": "Smooth FFD"}
BACKGROUND = np.array([1.0, 1.0, 1.0])


def load(path):
    img = plt.imread(path)   # float RGBA in [0, 1]
    if img.shape[-1] == 4:
        a = img[..., 3:4]
        img = img[..., :3] * a + BACKGROUND * (1 - a)
    return np.clip(img, 0, 1)


def figure(scene_dir, summary, out_path, width_in=12.8, dpi=100):
    look = summary.get("closeup_look", "zebra")
    rows = [("", "shaded"), ("_closeup", "close-up, reflection lines" if look == "zebra"
                              else "close-up, shaded")]
    imgs = [[load(os.path.join(scene_dir, f"{v}{suffix}.png")) for v in VARIANTS]
            for suffix, _ in rows]
    h, w = imgs[0][0].shape[:2]
    fig_h = width_in / 4 * h / w * len(rows) + 0.55
    fig, axes = plt.subplots(len(rows), 4, figsize=(width_in, fig_h), dpi=dpi)
    tris = summary.get("triangles", {})
    for r, (suffix, what) in enumerate(rows):
        for c, v in enumerate(VARIANTS):
            ax = axes[r, c]
            ax.imshow(imgs[r][c], interpolation="lanczos")
            ax.set_xticks([])
            ax.set_yticks([])
            for s in ax.spines.values():
                s.set_color("#bbbbbb")
            if r == 0:
                n = tris.get(v)
                ax.set_title(f"{LABELS[v]}" + (f"\n{n:,} triangles" if n else ""), fontsize=10)
        axes[r, 0].set_ylabel(what, fontsize=9)
    fig.suptitle(f"{summary['name']}: {summary.get('description', '')}", fontsize=10, y=0.995)
    fig.subplots_adjust(left=0.035, right=0.995, bottom=0.01, top=1 - 0.55 / fig_h - 0.02,
                        wspace=0.02, hspace=0.03)
    fig.savefig(out_path, dpi=dpi, facecolor="white")
    plt.close(fig)


def print_summary(summaries):
    print()
    print(f"{'scene':<10} {'input':>7} {'subsurf':>8} {'smooth':>8} {'patches':>8} "
          f"{'add-on ms':>9} {'core ms':>8} {'render s':>9}  OBJ")
    for s in summaries:
        t = s["triangles"]
        r = s.get("smooth_ffd_at_render", {})
        print(f"{s['name']:<10} {t['original']:>7} {t['lattice_subsurf']:>8} "
              f"{t['smooth_ffd'] or 0:>8} {r.get('patches', -1):>8} "
              f"{r.get('deform_ms', float('nan')):>9.1f} {s['core_deform_ms']:>8.1f} "
              f"{sum(s['render_s'].values()):>9.1f}  {os.path.relpath(s['obj'])}")
    print("input/subsurf/smooth: triangles (Lattice modifier = input); smooth = Smooth FFD at "
          "render level; add-on ms = its deform at render level (plan reused); core ms = "
          "smoothffd.Deformer.deform alone; render s = Cycles CPU, all 8 images of the scene.")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out/demo")
    ap.add_argument("--docs", default=None, help="folder for downscaled copies")
    ap.add_argument("--docs-scenes", nargs="*", default=["vase", "teapot", "knotbox"])
    ap.add_argument("scenes", nargs="*")
    a = ap.parse_args()
    scenes = a.scenes or sorted(d for d in os.listdir(a.out)
                                if os.path.exists(os.path.join(a.out, d, "summary.json")))
    summaries = []
    for name in scenes:
        d = os.path.join(a.out, name)
        with open(os.path.join(d, "summary.json")) as f:
            s = json.load(f)
        summaries.append(s)
        path = os.path.join(a.out, f"{name}.png")
        figure(d, s, path)
        print("wrote", path)
        if a.docs and name in a.docs_scenes:
            os.makedirs(a.docs, exist_ok=True)
            small = os.path.join(a.docs, f"demo_{name}.png")
            figure(d, s, small, width_in=7.6, dpi=80)
            print(f"wrote {small} ({os.path.getsize(small) // 1024} KB)")
    print_summary(summaries)


if __name__ == "__main__":
    main()
