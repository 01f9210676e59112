#!/usr/bin/env python3
"""Charts of speed against quality from a bench_builders JSON run.

    bench_builders --benchmark_filter=threads:2 --benchmark_repetitions=3 \
        --benchmark_report_aggregates_only=true --benchmark_out=builders.json --benchmark_out_format=json
    python3 benchmarks/plot.py builders.json docs/

With repetitions, each case's median (time and counters) is used; a run
without them is read as it is.
Writes, per scene, docs/builders_<scene>_sah.png (build time against SAH
cost relative to the binned-SAH builder, with the issue's targets: 1.15x and
1.05x, and Embree LOW's build time as a vertical line) and
docs/builders_<scene>_trace.png (build time against trace speed, primary and
random rays), one point per builder/setting at 2 threads, with the binned-SAH
builder and Embree LOW/MEDIUM/HIGH as reference points. Prints a Markdown
table per scene. Needs matplotlib (Debian: python3-matplotlib).
"""
import json
import os
import re
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = {
    "sah": "black",
    "pairwise": "tab:purple",
    "sortaxis (thesis: greedy)": "tab:blue",
    "sortaxis mutual": "tab:cyan",
    "ploc": "tab:olive",
    "ploc + post-pass": "tab:green",
    "embree": "tab:red",
}


def family(label):
    """Colour group of a benchmark label (builder/setting)."""
    if label.startswith("sortaxis/mutual"):
        return "sortaxis mutual"
    if label.startswith("sortaxis"):
        return "sortaxis (thesis: greedy)"
    if label.startswith("ploc"):
        return "ploc + post-pass" if label.endswith("/opt") else "ploc"
    return label.split("/")[0]


def short(label):
    return label.replace("sortaxis/", "").replace("pairwise/", "pw/").replace("mutual-", "m-")


def load(path):
    with open(path) as f:
        data = json.load(f)
    rows = defaultdict(list)  # scene -> [(label, family, threads, ms, sah, primary, random)]
    benches = data["benchmarks"]
    if any(b.get("aggregate_name") for b in benches):
        benches = [b for b in benches if b.get("aggregate_name") == "median"]
    for b in benches:
        if b.get("error_occurred"):
            continue
        name = re.sub(r"_median$", "", b["name"])
        name = re.sub(r"/(min_time|iterations|repeats):[^/]*|/real_time", "", name)
        m = re.match(r"builders/([^/]+)/(.+)/threads:(\d+)$", name)
        if not m:
            continue
        scene, label, threads = m.group(1), m.group(2), int(m.group(3))
        ms = b["real_time"] if b.get("time_unit") == "ms" else b["real_time"] / 1e6
        rows[scene].append((label, family(label), threads, ms, b.get("sah"), b.get("primary_Mrays"),
                            b.get("random_Mrays")))
    return rows


def chart(scene, rows, out_dir):
    pts = [r for r in rows if r[2] == 2]
    ref = next((r[4] for r in pts if r[0] == "sah"), None)
    low = next((r[3] for r in pts if r[0] == "embree/low"), None)
    # build time against SAH cost relative to binned SAH
    fig, ax = plt.subplots(figsize=(9, 6))
    for label, fam, _, ms, sah, _, _ in pts:
        if sah is None or fam == "embree" or not ref:
            continue
        ax.scatter(ms, sah / ref, color=COLOURS.get(fam, "gray"), s=28)
        ax.annotate(short(label), (ms, sah / ref), fontsize=6, xytext=(3, 2), textcoords="offset points")
    for fam, col in COLOURS.items():
        if fam != "embree":
            ax.scatter([], [], color=col, label=fam)
    if low:
        ax.axvline(low, color="tab:red", ls="--", lw=1, label=f"Embree LOW build ({low:.1f} ms)")
    for y, txt in ((1.15, "1.15x (sortaxis target)"), (1.05, "1.05x (PLOC target)")):
        ax.axhline(y, color="gray", ls=":", lw=1)
        ax.text(0.01, y, txt, transform=ax.get_yaxis_transform(), fontsize=7, color="gray", va="bottom")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("build time, ms (2 threads, log)")
    ax.set_ylabel("SAH cost / binned SAH's (Ct = Ci = 1, leaf <= 8, log; lower is better)")
    ax.set_title(f"{scene}: build time against tree quality")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, f"builders_{scene}_sah.png"), dpi=110)
    plt.close(fig)
    # build time against trace speed
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharex=True)
    for ax, idx, what in ((axes[0], 5, "primary"), (axes[1], 6, "random")):
        for r in pts:
            label, fam, ms, v = r[0], r[1], r[3], r[idx]
            if v is None:
                continue
            marker = "*" if fam == "embree" else "o"
            ax.scatter(ms, v, color=COLOURS.get(fam, "gray"), s=60 if marker == "*" else 26, marker=marker)
            ax.annotate(short(label), (ms, v), fontsize=6, xytext=(3, 2), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_xlabel("build time, ms (2 threads, log)")
        ax.set_ylabel(f"closest-hit Mrays/s, {what} rays (2 threads)")
        ax.set_title(f"{scene}: {what} rays")
        ax.grid(True, which="both", alpha=0.3)
    for fam, col in COLOURS.items():
        axes[0].scatter([], [], color=col, label=fam, marker="*" if fam == "embree" else "o")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, f"builders_{scene}_trace.png"), dpi=110)
    plt.close(fig)


def table(scene, rows):
    print(f"\n#### {scene} (2 threads)\n")
    print("| builder / setting | build ms | Mtris/s vs Embree LOW | SAH | SAH / binned SAH | primary Mrays/s | random Mrays/s |")
    print("|---|---|---|---|---|---|---|")
    ref = next((r[4] for r in rows if r[0] == "sah" and r[2] == 2), None)
    low = next((r[3] for r in rows if r[0] == "embree/low" and r[2] == 2), None)
    for label, fam, threads, ms, sah, pr, rn in sorted(rows, key=lambda r: r[3]):
        if threads != 2:
            continue
        ratio = f"{sah / ref:.3f}" if sah and ref else "-"
        sah_s = f"{sah:.2f}" if sah else "-"
        speed = f"{low / ms:.2f}x" if low else "-"
        print(f"| {label} | {ms:.1f} | {speed} | {sah_s} | {ratio} | {pr or 0:.2f} | {rn or 0:.2f} |")


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot.py BENCH_BUILDERS.json OUT_DIR")
    rows = load(sys.argv[1])
    os.makedirs(sys.argv[2], exist_ok=True)
    for scene, r in rows.items():
        chart(scene, r, sys.argv[2])
        table(scene, r)


if __name__ == "__main__":
    main()
