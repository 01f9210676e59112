#!/usr/bin/python3
"""Charts of the CPU renderer's image error against samples per pixel and texture filter.

    benchmarks/plot_render.py [CSV] [OUT_DIR]

CSV defaults to docs/render_spp_error.csv (written by `spp_error docs`), OUT_DIR to docs/.
Writes
  OUT_DIR/render_spp_error.png       RMSE against spp (log-log, bilinear filtering), one line per
                                     scene, with the 1/sqrt(spp) slope for reference and the
                                     render time of each point annotated
  OUT_DIR/render_texture_filter.png  RMSE against render time (error against cost), nearest vs
                                     bilinear, one panel per scene, points labelled with spp
Needs matplotlib (Debian: python3-matplotlib; run with /usr/bin/python3).
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    rows = defaultdict(list)  # (scene, filter) -> [(spp, rmse, ms)]
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            rows[(r["scene"], r["filter"])].append((int(r["spp"]), float(r["rmse"]), float(r["ms"])))
    for v in rows.values():
        v.sort()
    return rows


def plot_spp(rows, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    scenes = sorted({s for s, _ in rows})
    for scene in scenes:
        pts = rows.get((scene, "bilinear"))
        if not pts:
            continue
        spp = [p[0] for p in pts]
        err = [p[1] for p in pts]
        (line,) = ax.plot(spp, err, "o-", label=f"{scene}")
        for s, e, ms in pts:
            ax.annotate(f"{ms:.0f} ms", (s, e), textcoords="offset points", xytext=(4, 4), fontsize=7,
                        color=line.get_color())
        ax.plot(spp, [err[0] * (spp[0] / s) ** 0.5 for s in spp], ":", color=line.get_color(), alpha=0.6,
                label=f"{scene}: 1/sqrt(spp) from 1 spp")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("samples per pixel")
    ax.set_ylabel("RMSE vs 256-spp reference (linear RGB)")
    ax.set_title("CPU renderer: error against samples per pixel (320x240, 2 threads)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def plot_filter(rows, out):
    scenes = sorted({s for s, _ in rows})
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes), 4.2), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        for filt, marker in (("bilinear", "o-"), ("nearest", "s--")):
            pts = rows.get((scene, filt))
            if not pts:
                continue
            ax.plot([p[2] for p in pts], [p[1] for p in pts], marker, label=filt)
            for s, e, ms in pts:
                ax.annotate(f"{s}", (ms, e), textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("render time per frame (ms, 2 threads)")
        ax.set_ylabel("RMSE vs 256-spp bilinear reference")
        ax.set_title(f"{scene}: texture filter, error against cost\n(labels: spp)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    docs = os.path.join(here, "..", "docs")
    path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(docs, "render_spp_error.csv")
    out_dir = sys.argv[2] if len(sys.argv) > 2 else docs
    rows = read(path)
    if not rows:
        sys.exit(f"plot_render.py: no rows in {path}")
    os.makedirs(out_dir, exist_ok=True)
    a = os.path.join(out_dir, "render_spp_error.png")
    b = os.path.join(out_dir, "render_texture_filter.png")
    plot_spp(rows, a)
    plot_filter(rows, b)
    print(f"wrote {a}\nwrote {b}")


if __name__ == "__main__":
    main()
