#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Equal-time comparison of integrators (and of Mitsuba 3's path tracer) against the Mitsuba 3
references at several time budgets: Markdown tables, a JSON of every number, and
error-vs-time curves.

    bench/equal_time.py --scenes cbox_glass_sphere caustic_glass_light \\
                        --integrators path pssmlt gdmlt --times 5 10 20 \\
                        [--mitsuba-python /tmp/mi_venv/bin/python] [--repeats 3]

Runs
----
Every run is `gdmlt render SCENE --integrator I --time T -t THREADS --seed S` (plus --extra).
SCENE is a name looked up in ../shared/scenes/ (the files the references were rendered from)
and then in scenes/, or a path to an .xml file; it is compared with
--references/NAME.exr. Each configuration runs --repeats times with seeds 0, 1, ...; the
order is scene, budget, seed, integrator (interleaved: each seed runs every integrator back
to back), so that a change of machine load hits all integrators of one budget alike; a
measured 25% swing in speed between consecutive minutes made the earlier integrator-major
order favour whichever ran first. The machine may be shared: compare integrators within one
run of this script, never across runs.

An integrator may carry options as a variant, `NAME:KEY=VALUE[,KEY=VALUE...]`, which adds
`--KEY VALUE` to that run only (a bare `KEY` adds the flag `--KEY`), e.g. `--integrators gdpt
gdpt:shift=reconnect` compares GDPT with and without the manifold shift in one run.

Mitsuba
-------
"mitsuba" is a pseudo-integrator: Mitsuba 3's `path` integrator as the scene file configures
it, rendered in a child process by the interpreter --mitsuba-python (default: this one), see
bench/mitsuba_runner.py. It is added to the end of --integrators when Mitsuba can be
imported (list it explicitly to place it elsewhere; --no-mitsuba leaves it out). Variant
--mitsuba-variant (llvm_ad_rgb) or else scalar_rgb; threads limited to --threads with
drjit.set_thread_count. Equal time: a 4 spp calibration render measures the cost per spp,
then further passes are sized so that the render ends at about T seconds; the actual
seconds and spp are reported, and a render more than 5% over T is flagged. `-D name=value`
defines in --extra are passed to Mitsuba's scene loader too; other --extra options are
gdmlt-only.

Output (printed and written to --out)
-------------------------------------
* results.md, table 1, per scene, budget and integrator (medians over the repeats):
  time    measured render seconds (gdmlt: render_s, which for gdpt/gdmlt includes the
          reconstruction after the sampling budget; Mitsuba: all its passes);
  relMSE  bench/metrics.py rel_mse against the reference;
  mean    image mean / reference mean (over all pixels and channels): bias or energy loss
          shows here when relMSE is dominated by noise;
  raw relMSE / raw mean   the same for primal + very_direct layers of gdpt/gdmlt, i.e. the
          image before the gradient-domain reconstruction;
  FIRST/x relMSE(first integrator listed, Mitsuba aside) / relMSE(x);
  mitsuba/x relMSE(Mitsuba) / relMSE(x) at the same budget, > 1: x is better;
  followed by warnings: gdmlt runs with 0 mutations (the bootstrap used the whole budget),
  partial renders, render_s over 1.25 x the budget, Mitsuba renders over it by > 5%.
* table 2, cost per sample relative to a path-tracer sample on the same scene in the same
  run: path samples/s divided by the integrator's rate (path, gdpt: samples_per_s; pssmlt,
  gdmlt: mutations / chains_s, i.e. per proposal; Mitsuba: spp * pixels / seconds); medians
  over all budgets and repeats. Needs `path` among the integrators for the ratio.
* results.json: settings, Mitsuba version/variant/threads, every run, both tables.
* equal_time.png: relMSE vs budget per scene (every run as a dot, medians as a line).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import metrics  # noqa: E402
from mitsuba_runner import MitsubaRunner  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
SCENE_DIRS = [os.path.join(SHARED, "scenes"), os.path.join(ROOT, "scenes")]
MITSUBA = "mitsuba"
OVER_BUDGET = 1.25  # a gdmlt run longer than this x --time is flagged (reconstruction is extra)


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------

def parse_variant(spec):
    """'gdpt:shift=reconnect,foo=1,bar' -> ('gdpt', ['--shift', 'reconnect', '--foo', '1', '--bar']):
    a KEY without '=' is a flag (`--adap-mutual`)."""
    name, _, options = spec.partition(":")
    args = []
    for option in filter(None, options.split(",")):
        key, sep, value = option.partition("=")
        if not key or (sep and not value):
            raise SystemExit(f"integrator variant option {option!r} in {spec!r}: KEY=VALUE or KEY")
        args += [f"--{key}", value] if sep else [f"--{key}"]
    return name, args


def resolve_scene(name):
    """A scene name (cbox) or a path to an .xml file -> path of the scene file."""
    if name.endswith(".xml") and os.path.isfile(name):
        return os.path.abspath(name)
    for directory in SCENE_DIRS:
        path = os.path.join(directory, name + ".xml")
        if os.path.isfile(path):
            return path
    raise SystemExit(f"scene {name!r} not found in {' or '.join(SCENE_DIRS)}")


def scene_name(scene):
    return os.path.splitext(os.path.basename(scene))[0]


def defines_from_extra(extra):
    """The `-D name=value` / `--define name=value` / `-Dname=value` entries of gdmlt arguments."""
    defines, i = {}, 0
    while i < len(extra):
        arg = extra[i]
        value = None
        if arg in ("-D", "--define") and i + 1 < len(extra):
            value, i = extra[i + 1], i + 1
        elif arg.startswith("-D") and len(arg) > 2:
            value = arg[2:]
        elif arg.startswith("--define="):
            value = arg[len("--define="):]
        if value is not None and "=" in value:
            key, _, val = value.partition("=")
            defines[key] = val
        i += 1
    return defines


def image_metrics(image, reference):
    return {"rel_mse": metrics.rel_mse(image, reference),
            "mean_ratio": float(image.mean() / reference.mean())}


def raw_layers(exr):
    """primal + very_direct of a gradient-domain EXR (the image before reconstruction), or None
    when the EXR has no primal layer; very_direct is optional."""
    try:
        image = metrics.read_rgb(exr, "primal")
    except ValueError:
        return None
    try:
        image = image + metrics.read_rgb(exr, "very_direct")
    except ValueError:
        pass
    return image


# Integrators whose rate is mutations (chain proposals) per second of chains.
CHAIN_INTEGRATORS = ("pssmlt", "mmlt", "gdmlt")


def cost_rate(integrator, stats):
    """(samples or proposals per second, unit) from a gdmlt stats JSON, or (None, unit)."""
    if integrator in CHAIN_INTEGRATORS:
        if stats.get("mutations") and stats.get("chains_s"):
            return stats["mutations"] / stats["chains_s"], "proposal"
        return None, "proposal"  # no mutation ran (see run_warnings)
    return stats.get("samples_per_s"), "sample incl. shifts" if integrator == "gdpt" else "sample"


def run_warnings(integrator, stats, seconds):
    """What makes a gdmlt run not a fair point of an equal-time curve."""
    warnings = []
    if integrator in CHAIN_INTEGRATORS and not stats.get("mutations"):
        warnings.append(f"0 mutations (bootstrap {stats.get('bootstrap_s', 0):.2f} s used the budget)")
    if stats.get("partial"):
        warnings.append("partial render")
    if stats.get("render_s", 0) > OVER_BUDGET * seconds:
        warnings.append(f"render_s {stats['render_s']:.2f} s > {OVER_BUDGET:g} x budget")
    return warnings


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def fmt(value, spec):
    return "-" if value is None else format(value, spec)


def ratio(a, b):
    return a / b if a is not None and b else None


# --------------------------------------------------------------------------------------------
# Runs
# --------------------------------------------------------------------------------------------

def render_gdmlt(args, scene, spec, seconds, seed):
    integrator, variant_args = parse_variant(spec)
    tag = "_".join(a.lstrip("-") for a in variant_args)
    stem = f"{scene_name(scene)}_{integrator}{'_' + tag if tag else ''}_{seconds:g}s_seed{seed}"
    exr = os.path.join(args.out, stem + ".exr")
    stats_path = os.path.join(args.out, stem + ".json")
    cmd = [args.binary, "render", scene, "--integrator", integrator, "--time", str(seconds),
           "-t", str(args.threads), "--seed", str(seed), "-o", exr, "--stats", stats_path,
           "-q"] + variant_args + args.extra
    subprocess.run(cmd, check=True)
    with open(stats_path) as f:
        stats = json.load(f)
    rate, unit = cost_rate(integrator, stats)
    return exr, {"render_s": stats.get("render_s"), "rate": rate, "rate_unit": unit,
                 "warnings": run_warnings(integrator, stats, seconds),
                 "rays_total": stats.get("rays", {}).get("total"), "stats": stats_path}


def render_mitsuba(args, runner, scene, seconds, seed):
    exr = os.path.join(args.out, f"{scene_name(scene)}_{MITSUBA}_{seconds:g}s_seed{seed}.exr")
    info = runner.render(seconds, seed, exr)
    warnings = [f"{info['seconds']:.2f} s: over the budget by > 5%"] if info["overshoot"] else []
    return exr, {"render_s": info["seconds"], "rate": info["samples_per_s"], "rate_unit": "sample",
                 "warnings": warnings,
                 "spp": info["spp"], "chunks": info["chunks"], "overshoot": info["overshoot"],
                 "calibration_spp": info["calibration_spp"], "calibration_s": info["calibration_s"]}


def start_mitsuba(args):
    """A MitsubaRunner, or None (with the reason printed) when Mitsuba is not to be run."""
    wanted = MITSUBA in args.integrators
    if args.no_mitsuba:
        if wanted:
            raise SystemExit("--no-mitsuba contradicts 'mitsuba' in --integrators")
        return None, {"skipped": "--no-mitsuba"}
    runner = MitsubaRunner(args.mitsuba_python, args.threads, args.mitsuba_variant,
                           log_path=os.path.join(args.out, "mitsuba_worker.log"), cwd=ROOT)
    if not runner.available:
        message = f"Mitsuba 3: not run ({runner.error}; see --mitsuba-python)"
        if wanted:
            raise SystemExit(message)
        print(message, flush=True)
        return None, {"error": runner.error, "python": args.mitsuba_python}
    if not wanted:
        args.integrators.append(MITSUBA)
    return runner, {}


def describe_mitsuba(runner, args):
    info = dict(runner.info, python=args.mitsuba_python, libllvm=runner.libllvm,
                requested_variant=args.mitsuba_variant, notes=list(runner.notes))
    threads = (f"{info['thread_count']} threads (drjit.set_thread_count)" if info.get("thread_api")
               else "drjit.set_thread_count unavailable: all cores")
    notes = f"; {'; '.join(info['notes'])}" if info["notes"] else ""
    print(f"Mitsuba {info['version']} (drjit {info['drjit_version']}), variant {info['variant']}, "
          f"{threads}{', LLVM ' + info['libllvm'] if info['libllvm'] else ''}{notes}", flush=True)
    return info


def run_all(args, runner):
    runs = []
    extra_defines = defines_from_extra(args.extra)
    for name in args.scenes:
        scene = resolve_scene(name)
        reference_path = os.path.join(args.references, scene_name(scene) + ".exr")
        if not os.path.isfile(reference_path):
            raise SystemExit(f"no reference {reference_path}")
        reference = metrics.read_rgb(reference_path)
        print(f"{scene_name(scene)}: {scene}", flush=True)
        if runner is not None and MITSUBA in args.integrators:
            loaded = runner.load(scene, extra_defines)
            if "error" in loaded:
                raise SystemExit(f"Mitsuba cannot render {scene}: {loaded['error']}")
            print(f"  Mitsuba ({runner.info['variant']}) loaded in {loaded['load_s']:.2f} s, "
                  f"warm-up {loaded['warmup_s']:.2f} s (untimed)", flush=True)
        for seconds in args.times:
            for seed in range(args.repeats):
                for spec in args.integrators:
                    if spec == MITSUBA:
                        exr, run = render_mitsuba(args, runner, scene, seconds, seed)
                    else:
                        exr, run = render_gdmlt(args, scene, spec, seconds, seed)
                    run.update(scene=scene_name(scene), integrator=spec, budget_s=seconds, seed=seed,
                               exr=exr, **image_metrics(metrics.read_rgb(exr), reference))
                    raw = raw_layers(exr) if spec != MITSUBA else None
                    if raw is not None:
                        raw_metrics = image_metrics(raw, reference)
                        run.update(raw_rel_mse=raw_metrics["rel_mse"], raw_mean_ratio=raw_metrics["mean_ratio"])
                    runs.append(run)
                    line = (f"  {spec:22s} {seconds:6g} s seed {seed}: relMSE {run['rel_mse']:.5f}  "
                            f"mean {run['mean_ratio']:.4f}")
                    if "raw_rel_mse" in run:
                        line += f"  (raw: {run['raw_rel_mse']:.5f}, {run['raw_mean_ratio']:.4f})"
                    line += f"  [{fmt(run['render_s'], '.2f')} s"
                    if spec == MITSUBA:
                        line += f", {run['spp']} spp"
                    line += "]" + "".join(f"  WARNING: {w}" for w in run["warnings"])
                    print(line, flush=True)
    return runs


# --------------------------------------------------------------------------------------------
# Tables and plot
# --------------------------------------------------------------------------------------------

def baseline_integrator(args):
    """The integrator the `BASELINE/x` column divides by: the first one listed except Mitsuba,
    which has its own column."""
    return next((i for i in args.integrators if i != MITSUBA), None)


def summarise(args, runs):
    """Table 1 rows: medians per (scene, budget, integrator) and the ratios between them."""
    def select(scene, spec, seconds):
        return [r for r in runs if (r["scene"], r["integrator"], r["budget_s"]) == (scene, spec, seconds)]

    rows = []
    scenes = list(dict.fromkeys(r["scene"] for r in runs))
    for scene in scenes:
        for seconds in args.times:
            group = {}
            for spec in args.integrators:
                sel = select(scene, spec, seconds)
                group[spec] = {
                    "scene": scene, "budget_s": seconds, "integrator": spec, "n": len(sel),
                    "render_s": median(r["render_s"] for r in sel),
                    "rel_mse": median(r["rel_mse"] for r in sel),
                    "mean_ratio": median(r["mean_ratio"] for r in sel),
                    "raw_rel_mse": median(r.get("raw_rel_mse") for r in sel),
                    "raw_mean_ratio": median(r.get("raw_mean_ratio") for r in sel),
                }
                group[spec]["warnings"] = [f"seed {r['seed']}: {w}" for r in sel for w in r["warnings"]]
                if spec == MITSUBA:
                    group[spec]["spp"] = median(r["spp"] for r in sel)
            baseline = baseline_integrator(args)
            base = group[baseline]["rel_mse"] if baseline else None
            mitsuba = group[MITSUBA]["rel_mse"] if MITSUBA in group else None
            for spec, row in group.items():
                row["baseline_over_this"] = ratio(base, row["rel_mse"])
                row["mitsuba_over_this"] = ratio(mitsuba, row["rel_mse"])
                rows.append(row)
    return rows


def cost_table(args, runs):
    """Table 2 rows: per scene and integrator, rate and cost relative to one path sample."""
    rows = []
    for scene in dict.fromkeys(r["scene"] for r in runs):
        rates = {}
        for spec in args.integrators:
            sel = [r for r in runs if r["scene"] == scene and r["integrator"] == spec]
            if sel:
                rates[spec] = (median(r["rate"] for r in sel), sel[0]["rate_unit"], len(sel))
        path_rate = rates.get("path", (None,))[0]
        for spec, (rate, unit, n) in rates.items():
            rows.append({"scene": scene, "integrator": spec, "rate_per_s": rate, "unit": unit, "n": n,
                         "cost_vs_path_sample": ratio(path_rate, rate)})
    return rows


def markdown(args, rows, costs, mitsuba_info):
    first = baseline_integrator(args) or "baseline"
    lines = ["| scene | budget (s) | integrator | n | time (s) | relMSE | mean | raw relMSE | raw mean | "
             f"{first}/x | mitsuba/x |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['budget_s']:g} | {r['integrator']} | {r['n']} | "
                     f"{fmt(r['render_s'], '.2f')} | {fmt(r['rel_mse'], '.4g')} | {fmt(r['mean_ratio'], '.4f')} | "
                     f"{fmt(r['raw_rel_mse'], '.4g')} | {fmt(r['raw_mean_ratio'], '.4f')} | "
                     f"{fmt(r['baseline_over_this'], '.2f')} | {fmt(r['mitsuba_over_this'], '.2f')} |")
    notes = ["", "relMSE, mean (image mean / reference mean) and time: medians over the repeats. raw = "
             "primal + very_direct layers (gdpt/gdmlt before reconstruction). "
             f"{first}/x and mitsuba/x: ratios of median relMSE, > 1 means x has the lower error."]
    mitsuba_rows = [r for r in rows if r["integrator"] == MITSUBA]
    if mitsuba_rows:
        notes.append(f"Mitsuba {mitsuba_info.get('version')} {mitsuba_info.get('variant')}, "
                     f"{mitsuba_info.get('thread_count')} threads; median spp: " +
                     ", ".join(f"{r['scene']} @{r['budget_s']:g} s: {fmt(r['spp'], '.0f')}" for r in mitsuba_rows))
    warned = [r for r in rows if r["warnings"]]
    if warned:
        notes.append("Warnings:")
        notes += [f"- {r['scene']} @{r['budget_s']:g} s {r['integrator']}: {'; '.join(r['warnings'])}" for r in warned]
    lines += notes
    lines += ["", "| scene | integrator | n | rate (/s) | unit | cost / path sample |", "|---|---|---|---|---|---|"]
    for c in costs:
        lines.append(f"| {c['scene']} | {c['integrator']} | {c['n']} | {fmt(c['rate_per_s'], '.4g')} | "
                     f"{c['unit']} | {fmt(c['cost_vs_path_sample'], '.2f')} |")
    lines.append("")
    lines.append("cost / path sample = path samples/s / rate (medians over all budgets and repeats of the "
                 "scene); pssmlt/mmlt/gdmlt rate = mutations / chains_s." if any(c["integrator"] == "path" for c in costs)
                 else "no `path` runs: no cost ratios.")
    return "\n".join(lines)


def plot(args, runs, rows):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import matplotlib.ticker
    except ImportError:
        print("matplotlib not importable: no plot")
        return None
    scenes = list(dict.fromkeys(r["scene"] for r in runs))
    fig, axes = plt.subplots(1, len(scenes), figsize=(5 * len(scenes), 4), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        for spec in args.integrators:
            style = {"color": "black", "linestyle": "--"} if spec == MITSUBA else {}
            med = [(r["budget_s"], r["rel_mse"]) for r in rows
                   if r["scene"] == scene and r["integrator"] == spec and r["rel_mse"] is not None]
            line, = ax.loglog([m[0] for m in med], [m[1] for m in med], marker="o", label=spec, **style)
            pts = [(r["budget_s"], r["rel_mse"]) for r in runs if r["scene"] == scene and r["integrator"] == spec]
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=10, alpha=0.5, color=line.get_color())
        ax.set_xticks(args.times)
        ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_title(scene)
        ax.set_xlabel("time budget (s)")
        ax.set_ylabel("relative MSE")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    path = os.path.join(args.out, "equal_time.png")
    fig.savefig(path, dpi=100)
    return path


# --------------------------------------------------------------------------------------------

def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    parser.add_argument("--scenes", nargs="+", default=["cbox_glass_sphere", "caustic_glass_light"])
    parser.add_argument("--integrators", nargs="+", default=["path", "pssmlt"])
    parser.add_argument("--times", nargs="+", type=float, default=[5, 10, 20])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--references", default=os.path.join(SHARED, "references"))
    parser.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "equal_time"))
    parser.add_argument("--extra", default="", help="extra gdmlt arguments, e.g. '-D res=128'")
    parser.add_argument("--no-mitsuba", action="store_true", help="do not render with Mitsuba 3")
    parser.add_argument("--mitsuba-python", default=sys.executable,
                        help="interpreter that can import mitsuba (e.g. /tmp/mi_venv/bin/python)")
    parser.add_argument("--mitsuba-variant", default="llvm_ad_rgb", help="falls back to scalar_rgb")
    args = parser.parse_args()
    args.extra = args.extra.split()
    args.integrators = list(dict.fromkeys(args.integrators))
    for spec in args.integrators:
        if spec.startswith(MITSUBA + ":"):
            raise SystemExit("the mitsuba pseudo-integrator takes no options")
    if not os.path.isfile(args.binary) and any(i != MITSUBA for i in args.integrators):
        raise SystemExit(f"gdmlt binary not found: {args.binary} (build it first)")
    os.makedirs(args.out, exist_ok=True)

    runner, mitsuba_info = start_mitsuba(args)
    try:
        if runner is not None:
            mitsuba_info = describe_mitsuba(runner, args)
        runs = run_all(args, runner)
        if runner is not None:  # a fallback during a scene load changes the variant
            mitsuba_info = dict(mitsuba_info, variant=runner.info.get("variant"), notes=list(runner.notes))
    finally:
        if runner is not None:
            runner.close()

    rows = summarise(args, runs)
    costs = cost_table(args, runs)
    table = markdown(args, rows, costs, mitsuba_info)
    print()
    print(table)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(table + "\n")
    settings = {k: v for k, v in vars(args).items()}
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"settings": settings, "baseline": baseline_integrator(args), "mitsuba": mitsuba_info,
                   "runs": runs, "table": rows,
                   "cost": costs}, f, indent=2)
        f.write("\n")
    path = plot(args, runs, rows)
    print(f"\ntables: {os.path.join(args.out, 'results.md')}\nnumbers: {os.path.join(args.out, 'results.json')}"
          + (f"\nplot: {path}" if path else ""))


if __name__ == "__main__":
    main()
