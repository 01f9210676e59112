#!/usr/bin/env python3
"""Chart of the ray/triangle tests' speed against their accuracy, from a bench_tests JSON run.

    build-bench/benchmarks/bench_tests --benchmark_out=tests.json --benchmark_out_format=json
    /usr/bin/python3 benchmarks/plot_tests.py tests.json docs/

Writes docs/triangle_tests.png, two panels with x = random-ray closest-hit speed (Mrays/s, one
thread) per scene: left, y = misses of the 100,000 rays that must hit (edge_misses); right,
y = random rays answered with another triangle than brute force with the watertight test
(wrong_prim: a hit outside the triangle, or a hit where there is none). Symlog scales, so 0 is
drawn. Prints a Markdown table. Needs matplotlib (scripts/plots.sh installs it).
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

LABELS = {"watertight": "watertight (scalar)", "mt": "Möller–Trumbore", "thesis": "thesis (fixed tolerance)",
          "blocks": "watertight, 4-triangle blocks"}
MARKERS = {"bunny": "o", "torus100k": "s"}
COLOURS = {"watertight": "black", "mt": "tab:orange", "thesis": "tab:red", "blocks": "tab:blue"}


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    runs = json.load(open(sys.argv[1]))["benchmarks"]
    rows = []
    for b in runs:
        p = b["name"].split("/")
        if p[0] != "tests" or b.get("run_type", "iteration") != "iteration":
            continue
        rows.append((p[1], p[2], b["Mrays/s"], int(b["edge_misses"]), int(b["edge_rays"]), int(b["wrong_prim"])))
    fig, (ax, aw) = plt.subplots(1, 2, figsize=(11, 4.5), sharex=True)
    for scene, test, mrays, miss, _, wrong in rows:
        style = dict(marker=MARKERS.get(scene, "x"), color=COLOURS.get(test, "grey"), s=60)
        ax.scatter(mrays, miss, label=f"{LABELS.get(test, test)}, {scene}", **style)
        aw.scatter(mrays, wrong, **style)
    for a in (ax, aw):
        a.set_yscale("symlog", linthresh=1)
        a.set_ylim(bottom=-0.3)
        a.set_xlabel("random rays, closest hit, Mrays/s (1 thread; higher is better)")
        a.grid(True, alpha=0.3)
    ax.set_ylabel("misses of 100,000 rays at grid edges\n(must all hit; lower is better)")
    ax.set_title("cracks: rays through shared edges that miss")
    aw.set_ylabel("random rays with another triangle than brute force\n(of 262,144; lower is better)")
    aw.set_title("wrong triangle: hits outside the triangle")
    ax.legend(fontsize=7, loc="upper right", bbox_to_anchor=(1.0, 0.8))
    fig.suptitle("Ray/triangle tests: speed against accuracy")
    fig.tight_layout()
    out = os.path.join(sys.argv[2], "triangle_tests.png")
    fig.savefig(out, dpi=110)
    print("| scene | test | Mrays/s | misses / edge rays | wrong triangle / random rays |")
    print("|---|---|---|---|---|")
    for scene, test, mrays, miss, n, wrong in rows:
        print(f"| {scene} | {LABELS.get(test, test)} | {mrays:.2f} | {miss} / {n} | {wrong} / 262,144 |")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
