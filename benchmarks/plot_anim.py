#!/usr/bin/env python3
"""Charts of the animation data printed by benchmarks/anim_charts.cpp.

    /usr/bin/python3 benchmarks/plot_anim.py docs/anim_interp_error.csv docs/anim_sah_growth.csv docs/

writes
    docs/anim_interp_error.png  left: interpolation error (degrees from slerp,
                                mean and max over bones) against cost (ns per
                                bone) for slerp and Euler, one point per key-
                                frame stride; right: error against the real
                                key frame at the midpoint, by stride
    docs/anim_sah_growth.png    SAH of the goblin's tree over its animation:
                                refit-only / fresh build, and the RebuildPolicy
                                tree's growth since its last build, with the
                                rebuild frames marked and the 1.15 threshold
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def interp_chart(rows, out):
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for method, colour, marker in (("slerp", "tab:blue", "o"), ("euler", "tab:orange", "s")):
        rs = [r for r in rows if r["method"] == method]
        cost = [float(r["ns_per_bone"]) for r in rs]
        mean = [max(float(r["mean_deg_vs_slerp"]), 1e-7) for r in rs]
        worst = [max(float(r["max_deg_vs_slerp"]), 1e-7) for r in rs]
        a.scatter(cost, mean, color=colour, marker=marker, label=f"{method}: mean")
        a.scatter(cost, worst, color=colour, marker=marker, facecolors="none", label=f"{method}: max")
        for r, x, y in zip(rs, cost, mean):
            a.annotate(f"S={r['stride']}", (x, y), textcoords="offset points", xytext=(4, 3), fontsize=7)
        ks = [r for r in rs if r["mean_deg_vs_key"]]
        b.plot([int(r["stride"]) for r in ks], [float(r["mean_deg_vs_key"]) for r in ks], marker=marker,
               color=colour, label=f"{method}: mean")
        b.plot([int(r["stride"]) for r in ks], [float(r["max_deg_vs_key"]) for r in ks], marker=marker,
               color=colour, linestyle="--", label=f"{method}: max")
    a.set_yscale("log")
    a.set_xlabel("cost (ns per bone rotation, interpolate_poses)")
    a.set_ylabel("angle from slerp (degrees; slerp's ~1e-15 drawn at 1e-7)")
    a.set_title("Euler vs slerp: error against cost\n(goblin, 35 bones, t = 1/4, 1/2, 3/4; S = key-frame stride)",
                fontsize=9)
    a.legend(fontsize=7)
    b.set_xscale("log", base=2)
    b.set_yscale("log")
    b.set_xlabel("key-frame stride S (frames)")
    b.set_ylabel("angle from the real frame f + S/2 (degrees)")
    b.set_title("error at the midpoint against the skipped key frame", fontsize=9)
    b.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=120)


def sah_chart(rows, out):
    f = [int(r["frame"]) for r in rows]
    fig, ax = plt.subplots(figsize=(11, 4.2))
    ax.plot(f, [float(r["refit_only_vs_fresh"]) for r in rows], color="tab:red", lw=1,
            label="refit only (built at frame 0): SAH / fresh SAH")
    ax.plot(f, [float(r["sah_policy"]) / float(r["sah_fresh"]) for r in rows], color="tab:blue", lw=1,
            label="RebuildPolicy tree: SAH / fresh SAH")
    ax.plot(f, [float(r["growth"]) for r in rows], color="tab:green", lw=0.8, alpha=0.8,
            label="RebuildPolicy growth (SAH / SAH after its last build)")
    rb = [r for r in rows if r["rebuilt"] == "1"]
    ax.scatter([int(r["frame"]) for r in rb], [float(r["growth"]) for r in rb], color="black", marker="v", zorder=5,
               label=f"rebuild ({len(rb)} of {len(rows)} frames)")
    ax.axhline(1.15, color="gray", linestyle=":", label="threshold 1.15")
    ax.set_xlabel("goblin animation frame")
    ax.set_ylabel("SAH ratio")
    ax.set_title("SAH growth under refit over the goblin animation (1,679 vertices, 2,363 triangles)", fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(out, dpi=120)


def main():
    if len(sys.argv) != 4:
        print(__doc__)
        return 2
    out = sys.argv[3].rstrip("/")
    interp_chart(read(sys.argv[1]), out + "/anim_interp_error.png")
    sah_chart(read(sys.argv[2]), out + "/anim_sah_growth.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
