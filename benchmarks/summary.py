#!/usr/bin/env python3
"""Markdown summary of raykit's Google Benchmark JSON output (bench_trace, bench_build).

    build-bench/benchmarks/bench_trace --benchmark_out=trace.json --benchmark_out_format=json
    build-bench/benchmarks/bench_build --benchmark_out=build.json --benchmark_out_format=json
    python3 benchmarks/summary.py trace.json build.json

Case names (suffixes Google Benchmark appends, such as /min_time:0.500 or /real_time,
are ignored):
    trace/<scene>/<rays>/<query>/<raykit|wide8|block8|batch|embree|embree_high|embree16>/threads:<T>
    build/<scene>/raykit/threads:<T>
    build/<scene>/embree_scene/quality:<q>/threads:<T>
    sahcmp/<scene>/leaf:<L>/<raykit|embree_builder>
Other cases (e.g. bench_obj's) are listed with their time and items/s.
Standard library only.
"""
import argparse
import json
import math
import sys

SUFFIX_PREFIXES = ("min_time:", "min_warmup_time:", "iterations:", "repeats:", "real_time", "process_time",
                   "manual_time")


def base_name(name):
    parts = name.split("/")
    while parts and parts[-1].startswith(SUFFIX_PREFIXES):
        parts.pop()
    return "/".join(parts)


def to_ms(value, unit):
    scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}.get(unit, 1.0)
    return value * scale


def fmt(x, digits=2):
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if isinstance(x, float):
        return f"{x:.{digits}f}"
    return str(x)


def ratio(a, b):
    if a is None or b is None or b == 0:
        return None
    return a / b


def table(headers, rows):
    out = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    for r in rows:
        out.append("| " + " | ".join(fmt(c) if not isinstance(c, str) else c for c in r) + " |")
    return "\n".join(out)


def load(paths):
    runs, errors = [], []
    for p in paths:
        with open(p, encoding="utf-8") as f:
            data = json.load(f)
        for b in data.get("benchmarks", []):
            if b.get("run_type", "iteration") != "iteration":
                continue  # aggregates (mean/median/stddev) of repetitions
            name = base_name(b.get("run_name", b["name"]))
            if b.get("error_occurred"):
                errors.append((name, b.get("error_message", "")))
                continue
            b["_name"] = name
            runs.append(b)
    return runs, errors


def mrays(b):
    ips = b.get("items_per_second")
    return ips * 1e-6 if ips is not None else None


def trace_section(runs):
    cases = {}
    order = []
    for b in runs:
        p = b["_name"].split("/")
        if len(p) != 6 or p[0] != "trace":
            continue
        _, scene, rays, query, lib, threads = p
        key = (scene, rays, query, threads.replace("threads:", ""))
        if key not in cases:
            cases[key] = {}
            order.append(key)
        cases[key][lib] = b
    if not cases:
        return None
    rows = []
    for key in order:
        c = cases[key]
        rk, em = mrays(c["raykit"]) if "raykit" in c else None, mrays(c["embree"]) if "embree" in c else None
        w8 = mrays(c["wide8"]) if "wide8" in c else None
        b8 = mrays(c["block8"]) if "block8" in c else None
        mm = None
        for lib in ("raykit", "embree"):
            if lib in c and "mismatch" in c[lib]:
                mm = int(c[lib]["mismatch"])
        bd = int(c["block8"]["block_vs_binary"]) if "block8" in c and "block_vs_binary" in c["block8"] else None
        bt = mrays(c["batch"]) if "batch" in c else None
        eh = mrays(c["embree_high"]) if "embree_high" in c else None
        e16 = mrays(c["embree16"]) if "embree16" in c else None
        bvs = int(c["batch"]["batch_vs_single"]) if "batch" in c and "batch_vs_single" in c["batch"] else None
        hit = c.get("raykit", c.get("embree", {})).get("hit_frac")
        rows.append(list(key) + [rk, w8, b8, bt, em, eh, e16, ratio(rk, em), ratio(b8, em), ratio(b8, eh),
                                 ratio(bt, e16), fmt(hit, 3) if hit is not None else "–",
                                 str(mm) if mm is not None else "–", str(bd) if bd is not None else "–",
                                 str(bvs) if bvs is not None else "–"])
    return ("### Tracing (Mrays/s, higher is better; raykit = binary Bvh, wide8 = the same tree as a "
            "WideBvh8, block8 = BlockBvh8::build: a tree built for 4-triangle blocks, 8-wide; batch = "
            "block8 through the batch call (packets of coherent rays); Embree MEDIUM and HIGH rtcIntersect1, "
            "Embree16 = rtcIntersect16 on MEDIUM)\n\n" +
            table(["scene", "rays", "query", "threads", "raykit", "wide8", "block8", "batch", "Embree",
                   "Embree HIGH", "Embree16", "raykit/Embree", "block8/Embree", "block8/Embree HIGH",
                   "batch/Embree16", "hit frac", "mismatch vs Embree", "block8 vs binary",
                   "batch vs block8"], rows))


def build_section(runs):
    rows = []
    for b in runs:
        p = b["_name"].split("/")
        if len(p) < 4 or p[0] != "build":
            continue
        scene, builder = p[1], p[2]
        threads = p[-1].replace("threads:", "")
        if builder == "embree_scene":
            builder = "Embree scene, " + p[3].replace("quality:", "")
        ips = b.get("items_per_second")
        rows.append([scene, builder, threads, ips * 1e-6 if ips else None, to_ms(b["real_time"], b["time_unit"]),
                     fmt(b.get("sah"), 2) if "sah" in b else "–"])
    if not rows:
        return None
    return "### BVH build (whole mesh to tree)\n\n" + table(
        ["scene", "builder", "threads", "Mtris/s", "ms", "SAH"], rows)


def sah_section(runs):
    cases, order = {}, []
    for b in runs:
        p = b["_name"].split("/")
        if len(p) != 4 or p[0] != "sahcmp":
            continue
        key = (p[1], p[2].replace("leaf:", ""))
        if key not in cases:
            cases[key] = {}
            order.append(key)
        cases[key][p[3]] = b
    if not cases:
        return None
    rows = []
    for key in order:
        c = cases[key]
        rk, em = c.get("raykit"), c.get("embree_builder")
        rs, es = (rk or {}).get("sah"), (em or {}).get("sah")
        rt = to_ms(rk["real_time"], rk["time_unit"]) if rk else None
        et = to_ms(em["real_time"], em["time_unit"]) if em else None
        rows.append(list(key) + [rs, es, fmt(ratio(rs, es), 4) if ratio(rs, es) is not None else "–",
                                 str(int(rk["nodes"])) if rk and "nodes" in rk else "–",
                                 str(int(em["nodes"])) if em and "nodes" in em else "–", rt, et])
    return ("### SAH quality: raykit BinnedSahBuilder vs Embree rtcBuildBVH (binary, MEDIUM), Ct = Ci = 1\n\n" +
            table(["scene", "max leaf", "raykit SAH", "Embree SAH", "SAH raykit/Embree", "raykit nodes",
                   "Embree nodes", "raykit ms", "Embree ms"], rows))


def other_section(runs):
    rows = []
    for b in runs:
        if b["_name"].split("/")[0] in ("trace", "build", "sahcmp"):
            continue
        ips = b.get("items_per_second")
        rows.append([b["_name"], to_ms(b["real_time"], b["time_unit"]), ips * 1e-6 if ips else None])
    if not rows:
        return None
    return "### Other cases\n\n" + table(["case", "ms", "M items/s"], rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("json", nargs="+", help="Google Benchmark JSON output files")
    args = ap.parse_args(argv)
    runs, errors = load(args.json)
    sections = [s for s in (trace_section(runs), build_section(runs), sah_section(runs), other_section(runs)) if s]
    if errors:
        sections.append("### Skipped / failed\n\n" + "\n".join(f"- `{n}`: {m}" for n, m in errors))
    if not sections:
        print("no benchmark results found", file=sys.stderr)
        return 1
    print("\n\n".join(sections))
    return 0


if __name__ == "__main__":
    sys.exit(main())
