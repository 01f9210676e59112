#!/usr/bin/env python3
"""Chart of the ray/triangle tests' speed against their accuracy, from a bench_tests JSON run.

    build-bench/benchmarks/bench_tests --benchmark_out=tests.json --benchmark_out_format=json
    /usr/bin/python3 benchmarks/plot_tests.py tests.json docs/

Writes docs/triangle_tests.png: x = random-ray closest-hit speed (Mrays/s, one thread) per
scene, y = misses of the 100,000 rays that must hit (edge_misses, symlog scale: 0 is drawn).
Prints a Markdown table. Needs matplotlib (Debian: python3-matplotlib).
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
        rows.append((p[1], p[2], b["Mrays/s"], int(b["edge_misses"]), int(b["edge_rays"])))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for scene, test, mrays, miss, _ in rows:
        ax.scatter(mrays, miss, marker=MARKERS.get(scene, "x"), color=COLOURS.get(test, "grey"), s=60,
                   label=f"{LABELS.get(test, test)}, {scene}")
    ax.set_yscale("symlog", linthresh=1)
    ax.set_xlabel("random rays, closest hit, Mrays/s (1 thread; higher is better)")
    ax.set_ylabel("misses of 100,000 rays at grid edges\n(must all hit; lower is better)")
    ax.set_title("Ray/triangle tests: speed against watertightness")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="center right")
    fig.tight_layout()
    out = os.path.join(sys.argv[2], "triangle_tests.png")
    fig.savefig(out, dpi=110)
    print("| scene | test | Mrays/s | misses / rays |")
    print("|---|---|---|---|")
    for scene, test, mrays, miss, n in rows:
        print(f"| {scene} | {LABELS.get(test, test)} | {mrays:.2f} | {miss} / {n} |")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
