#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""What accuracy costs in time: one command, one self-contained report.

    bench/study.py --quick        # about 10 minutes on 2 cores
    bench/study.py                # the full study, a few hours
    bench/study.py --quick --scenes cbox --times 0.5 --define res=24 --no-mitsuba   # a smoke run

Writes OUT/report.md (default bench/out/study/), the PNG figures beside it and OUT/study.json
(every number of the report, with the settings and the versions). It runs the `gdmlt`
executable as a user does (--binary, default build/release/gdmlt, which the README's first
command builds) and the Google Benchmark executables beside it (build/release/bench/).

Scenes and references
---------------------
The scenes are those of scenes/ (or --scenes, names or .xml paths). A scene with the same name
in ../shared/scenes is taken from there, with its Mitsuba 3 reference from
../shared/references, when that directory exists and no --define changes the scene. Otherwise
the study makes its own reference and caches it under bench/out/references (NAME.exr and
NAME.json: how it was made, from which scene file (SHA-256) and defines, and its own noise):
Mitsuba 3's path tracer when Mitsuba is importable by --mitsuba-python, else a long run of our
path tracer. A reference is the mean of two independent halves (different seeds); its noise is
given as relMSE(half a, half b) / 4, which is about the relMSE of the mean against the
converged image while the noise is small against the signal: an error in the tables near that
value is the reference's, not the renderer's.

Metric: relMSE = mean over pixels and RGB of (x - ref)^2 / (ref^2 + 0.01) (bench/metrics.py),
always given with the image mean / reference mean ("mean"): a darker image can score a better
relMSE. Ratios "mitsuba/x" are relMSE(Mitsuba 3 path) / relMSE(x) in the same run (> 1: x is
better), so that machines of different speed compare.

Sections of the report
----------------------
1. Equal-time matrix: every integrator (and Mitsuba 3) x scene x budget, error-vs-time
   curves, a montage of equal-time crops.
2. The price of each knob (on --knob-scene): GDMLT's shift family, primal weight, large-step
   probability, mutation size, neighbours, bidirectional samples (auto, off, on) and where
   bidirectional GDMLT's light tracing comes from; the reconstruction method,
   alpha and iteration count offline on one raw render; the manifold walk's tolerance and
   iteration cap (bench_manifold).
3. The shift table: per family, similarity (variance of the GDPT differences over that of the
   primal, both from the render's variance layers), correctness (mean z^2 of the differences
   against the reference's pixel differences, 1 = no bias visible), invertibility and
   efficiency (bench_shifts: round-trip rate, success rate, time per shift).
4. The reconstruction table: solve time at 1280x720's pixel count, error under injected
   outliers, bias (mean ratio, low-pass relMSE) per method.
5. ADAP vs lattice neighbours at equal time, with a picture of the chosen edges.
6. What ran: per scene and integrator, the machinery the stats say was used and where the
   time went (a scene without specular surfaces runs no manifold walk).
"""
import argparse
import hashlib
import json
import os
import re
import shlex
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import equal_time  # noqa: E402
import metrics  # noqa: E402

ROOT = os.path.dirname(HERE)
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
MITSUBA = "mitsuba"
INTEGRATORS = ["path", "bdpt", "pssmlt", "gdpt", "gdmlt"]
SHIFT_FAMILIES = ["auto", "reconnect", "halfvector", "replay"]
RECONSTRUCTIONS = ["primal", "l1", "huber", "l2", "cv"]
SECTION_TITLES = {
    1: "Equal-time matrix",
    2: "The price of each accuracy knob",
    3: "The shift table, measured",
    4: "The reconstruction table, measured",
    5: "ADAP vs lattice neighbours at equal time",
    6: "What ran",
}

# Budgets and sizes per mode. quick: ~10 minutes on 2 cores for the five scenes of scenes/
# (section 1 is 5 scenes x 5 s x 6 renderers), plus up to 3-4 minutes for references the first
# time on a clone without ../shared; full: a few hours (3 seeds, up to 64 s).
MODES = {
    "quick": {"times": [1.0, 4.0], "seeds": 1, "knob_time": 4.0, "knob_seeds": 1, "shift_spp": 8,
              "adap_times": [4.0], "reference_s": 20.0, "reference_spp": 256,
              "bench_min_time": 0.05, "reconstruct_repeats": 1},
    "full": {"times": [4.0, 16.0, 64.0], "seeds": 3, "knob_time": 16.0, "knob_seeds": 3,
             "shift_spp": 64, "adap_times": [16.0, 64.0], "reference_s": 600.0,
             "reference_spp": 16384, "bench_min_time": 0.5, "reconstruct_repeats": 3},
}


# --------------------------------------------------------------------------------------------
# Pure helpers (unit-tested in tests/bench/test_study.py)
# --------------------------------------------------------------------------------------------

def fmt(value, spec=".4g"):
    """A table cell: '-' for missing or non-finite values."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return format(float(value), spec) if np.isfinite(value) else "-"
    return str(value)


def md_table(headers, rows):
    """Markdown table; cells through fmt()."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for row in rows:
        if len(row) != len(headers):
            raise ValueError(f"row {row!r} has {len(row)} cells, the header {len(headers)}")
        lines.append("| " + " | ".join(fmt(c) for c in row) + " |")
    return "\n".join(lines)


def median(values):
    values = [v for v in values if v is not None and np.isfinite(v)]
    return statistics.median(values) if values else None


def ratio(a, b):
    return a / b if a is not None and b else None


def scene_name(scene):
    return os.path.splitext(os.path.basename(scene))[0]


def reference_noise(half_a, half_b):
    """relMSE of the mean of two independent halves against the converged image, estimated
    from their difference: E[(a - b)^2] = 2 s^2 for per-half variance s^2, and the mean's error
    variance is s^2 / 2, a quarter of it (the relMSE's denominator taken from the mean)."""
    mean = 0.5 * (half_a + half_b)
    return float(np.mean((half_a - half_b) ** 2 / (mean ** 2 + 0.01)) / 4.0)


def difference_variance_ratio(primal_variance, difference_variances):
    """Similarity of a shift: the summed variance of the estimated differences over the summed
    variance of the primal (per direction, so that 2 means base and offset are uncorrelated
    and of equal variance, 0 that the offset cancels the base's noise exactly)."""
    total_primal = float(np.nansum(primal_variance))
    if total_primal <= 0.0:
        return None
    per_direction = [float(np.nansum(v)) for v in difference_variances]
    return float(np.mean(per_direction)) / total_primal


def gradient_error_ratio(difference, variance, primal, primal_variance, axis):
    """Correctness of estimated differences d(p) = I(p + e) - I(p) along `axis` (1: x, 0: y),
    checked against the differences of an independent primal estimate (another render with
    another seed, and its variance layer): sum (d - (I'(p + e) - I'(p)))^2 over the sum of the
    variances the two renders estimated for the terms, over edges where everything is finite.
    About 1 when the differences are unbiased (both estimates then have the same expectation);
    a bias adds its square to the numerator. Summed rather than a mean of per-edge z^2: variance
    estimates of a few samples are too noisy to divide by one at a time, their sum is not.
    (A reference image would do instead of I' only if its own noise were known: its pixel noise
    enters every difference, while the estimated differences can have far less.)"""
    if axis == 1:
        here, there = (slice(None), slice(None, -1)), (slice(None), slice(1, None))
    else:
        here, there = (slice(None, -1), slice(None)), (slice(1, None), slice(None))
    expected = primal[there] - primal[here]
    total = variance[here] + primal_variance[there] + primal_variance[here]
    d = difference[here]
    mask = np.isfinite(d) & np.isfinite(total) & np.isfinite(expected)
    total_variance = float(np.sum(total[mask]))
    if total_variance <= 0.0:
        return None
    return float(np.sum((d[mask] - expected[mask]) ** 2)) / total_variance


def inject_outliers(image, fraction, scale, rng):
    """A copy of `image` (HxWx3) where a `fraction` of the pixels (at least one) get `scale`
    times the image's mean absolute value added to every channel: isolated fireflies."""
    out = image.copy()
    h, w = image.shape[:2]
    count = max(1, int(round(fraction * h * w)))
    idx = rng.choice(h * w, size=count, replace=False)
    spike = scale * float(np.mean(np.abs(image[np.isfinite(image)]))) if np.isfinite(image).any() else scale
    out.reshape(h * w, -1)[idx] += spike
    return out


_SOLVE_SECONDS = re.compile(r"(\d+(?:\.\d+)?) s \(setup (\d+(?:\.\d+)?) s\)")


def parse_reconstruct_seconds(line):
    """Solve seconds (and setup seconds) from `gdmlt reconstruct`'s summary line."""
    m = _SOLVE_SECONDS.search(line)
    if not m:
        raise ValueError(f"no timing in reconstruct output: {line!r}")
    return float(m.group(1)), float(m.group(2))


STAGES = ("bootstrap_s", "very_direct_s", "light_tracing_s", "feature_pass_s", "selection_s", "reconstruct_s")


def what_ran(stats):
    """Machinery flags, work counts and time shares from a `gdmlt render --stats` JSON."""
    machinery = stats.get("machinery", {})
    shifts = stats.get("shifts", {})
    render_s = stats.get("render_s") or 0.0
    row = {
        "manifold_solver": bool(machinery.get("manifold_solver")),
        "shift_mappings": bool(machinery.get("shift_mappings")),
        "light_tracing": bool(machinery.get("light_tracing")),
        "markov_chains": bool(machinery.get("markov_chains")),
        "why": machinery.get("why", ""),
        "render_s": render_s,
        "rays": stats.get("rays", {}).get("total"),
        "shifts": shifts.get("total", 0),
        "manifold_walks": shifts.get("manifold_walks", 0),
        "manifold_iterations": shifts.get("manifold_newton_iterations", 0),
        "shift_ok_rate": (shifts["by_status"]["ok"] / shifts["total"]
                          if shifts.get("total") and "by_status" in shifts else None),
        "nonfinite_dropped": stats.get("nonfinite_samples_dropped", 0),
    }
    seconds = dict(stats, selection_s=stats.get("neighbour_selection", {}).get("selection_s"))
    shares = {}
    for stage in STAGES:
        if seconds.get(stage) is not None and render_s > 0:
            shares[stage] = seconds[stage] / render_s
    row["time_shares"] = shares
    return row


def adap_seconds(stats):
    """Seconds of ADAP's feature pass and neighbour selection in a render's stats (0 without)."""
    return (stats.get("feature_pass_s") or 0.0) + (stats.get("neighbour_selection", {}).get("selection_s") or 0.0)


def rate_of(integrator, stats):
    """Samples (path, bdpt, gdpt) or proposals (chains) per second of a render."""
    if stats.get("mutations") and stats.get("chains_s"):
        return stats["mutations"] / stats["chains_s"]
    return stats.get("samples_per_s")


def pyplot():
    """matplotlib.pyplot without a display (imported on first use: the helpers above need
    only numpy)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def tonemap(image, exposure=1.0):
    """sRGB-ish 8-bit preview (clamped, gamma 2.2) of a linear HxWx3 image."""
    return np.clip(np.nan_to_num(image * exposure) ** (1.0 / 2.2), 0.0, 1.0)


# --------------------------------------------------------------------------------------------
# The study
# --------------------------------------------------------------------------------------------

class Study:
    def __init__(self, args):
        self.args = args
        self.mode = dict(MODES["quick" if args.quick else "full"])
        if args.times:
            self.mode["times"] = args.times
            self.mode["knob_time"] = args.times[-1]
            self.mode["adap_times"] = [args.times[-1]]
        if args.seeds:
            self.mode["seeds"] = self.mode["knob_seeds"] = args.seeds
        if args.reference_spp:
            self.mode["reference_spp"] = args.reference_spp
        if args.reference_s:
            self.mode["reference_s"] = args.reference_s
        if args.bench_min_time:
            self.mode["bench_min_time"] = args.bench_min_time
        self.defines = dict(d.split("=", 1) for d in args.define)
        self.out = os.path.abspath(args.out)
        self.runs_dir = os.path.join(self.out, "runs")
        os.makedirs(self.runs_dir, exist_ok=True)
        self.started = time.perf_counter()
        self.runner = None
        self.mitsuba_info = {"skipped": "--no-mitsuba"} if args.no_mitsuba else {}
        self.data = {"settings": {"mode": "quick" if args.quick else "full", **self.mode,
                                  "defines": self.defines, "threads": args.threads,
                                  "binary": args.binary, "command": " ".join(map(shlex.quote, sys.argv))},
                     "references": {}, "sections": {}}
        self.references = {}
        self.independent = {}

    # ---- progress and processes ----

    def log(self, text):
        elapsed = time.perf_counter() - self.started
        print(f"[{int(elapsed // 60):02d}:{int(elapsed % 60):02d}] {text}", flush=True)

    def define_args(self):
        return [a for k, v in self.defines.items() for a in ("-D", f"{k}={v}")]

    def command_line(self, scene, integrator, extra, budget):
        """The gdmlt command a user runs for one render of the report (printed with figures)."""
        return " ".join(["gdmlt", "render", os.path.relpath(scene, ROOT) if scene.startswith(ROOT) else scene,
                         "--integrator", integrator] + budget + extra + self.define_args())

    def render(self, scene, integrator, extra=(), seconds=None, spp=None, seed=0, tag=""):
        """One `gdmlt render`; returns the EXR path and the stats dict."""
        budget = ["--time", f"{seconds:g}"] if seconds else ["--spp", str(spp)]
        stem = f"{scene_name(scene)}_{integrator}{'_' + tag if tag else ''}_{budget[1]}{budget[0][2]}_s{seed}"
        exr = os.path.join(self.runs_dir, stem + ".exr")
        stats_path = os.path.join(self.runs_dir, stem + ".json")
        cmd = [self.args.binary, "render", scene, "--integrator", integrator, "-t", str(self.args.threads),
               "--seed", str(seed), "-o", exr, "--stats", stats_path, "-q"] + budget + list(extra) + self.define_args()
        subprocess.run(cmd, check=True)
        with open(stats_path) as f:
            return exr, json.load(f)

    def bench_binary(self, name):
        path = os.path.join(self.args.bench_dir, name)
        if not os.path.isfile(path):
            raise SystemExit(f"benchmark executable not found: {path} (cmake --build --preset release)")
        return path

    def run_benchmark(self, name, env=None, flt="."):
        cmd = [self.bench_binary(name), "--benchmark_format=json",
               f"--benchmark_min_time={self.mode['bench_min_time']}", f"--benchmark_filter={flt}"]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True,
                             env=dict(os.environ, **(env or {}))).stdout
        return [b for b in json.loads(out)["benchmarks"] if b.get("run_type", "iteration") == "iteration"]

    # ---- scenes and references ----

    def scenes(self):
        names = self.args.scenes or sorted(scene_name(f) for f in os.listdir(os.path.join(ROOT, "scenes"))
                                           if f.endswith(".xml"))
        return [self.resolve_scene(n) for n in names]

    @staticmethod
    def resolve_scene(name):
        """A scene name (looked up in ../shared/scenes, then scenes/) or an .xml path."""
        return equal_time.resolve_scene(name)

    def start_mitsuba(self):
        if self.args.no_mitsuba:
            return
        from mitsuba_runner import MitsubaRunner
        runner = MitsubaRunner(self.args.mitsuba_python, self.args.threads, "llvm_ad_rgb",
                               log_path=os.path.join(self.out, "mitsuba_worker.log"), cwd=ROOT)
        if not runner.available:
            self.log(f"Mitsuba 3 not importable by {self.args.mitsuba_python} ({runner.error}): "
                     "no Mitsuba yardstick; references from our path tracer")
            self.mitsuba_info = {"error": runner.error, "python": self.args.mitsuba_python}
            return
        self.runner = runner
        self.mitsuba_info = dict(runner.info, python=self.args.mitsuba_python)
        self.log(f"Mitsuba {runner.info.get('version')} ({runner.info.get('variant')}) in the same run")

    def load_mitsuba(self, scene):
        loaded = self.runner.load(scene, self.defines)
        if "error" in loaded:
            raise SystemExit(f"Mitsuba cannot load {scene}: {loaded['error']}")

    def reference(self, scene):
        """(HxWx3 reference, description) for a scene, made and cached when needed."""
        name = scene_name(scene)
        if name in self.references:
            return self.references[name]
        shared = os.path.join(SHARED, "references", name + ".exr")
        if not self.defines and os.path.isfile(shared) and scene.startswith(os.path.join(SHARED, "scenes")):
            info = {"source": "../shared/references (Mitsuba 3, see its README)", "path": shared, "noise_rel_mse": None}
            self.references[name] = (metrics.read_rgb(shared), info)
            self.data["references"][name] = info
            return self.references[name]
        cache = os.path.abspath(self.args.reference_cache)
        os.makedirs(cache, exist_ok=True)
        key = name + "".join(f"_{k}-{v}" for k, v in sorted(self.defines.items()))
        exr, meta_path = os.path.join(cache, key + ".exr"), os.path.join(cache, key + ".json")
        with open(scene, "rb") as f:
            digest = hashlib.sha256(f.read()).hexdigest()
        wanted = {"scene": name, "scene_sha256": digest, "defines": self.defines}
        if os.path.isfile(exr) and os.path.isfile(meta_path):
            with open(meta_path) as f:
                meta = json.load(f)
            if all(meta.get(k) == v for k, v in wanted.items()):
                self.log(f"{name}: cached reference {exr} ({meta['made_by']})")
                self.references[name] = (metrics.read_rgb(exr), dict(meta, path=exr))
                self.data["references"][name] = self.references[name][1]
                return self.references[name]
        halves = []
        if self.runner is not None:
            self.load_mitsuba(scene)
            seconds = self.mode["reference_s"]
            for h in range(2):
                half = os.path.join(cache, f"{key}_half{h}.exr")
                self.log(f"{name}: reference half {h + 1}/2 with Mitsuba 3 ({seconds:g} s)")
                self.runner.render(seconds, 1000 + h, half)
                halves.append(metrics.read_rgb(half))
            made_by = (f"Mitsuba 3 {self.mitsuba_info.get('version')} {self.runner.info.get('variant')} path "
                       f"tracer, 2 x {seconds:g} s")
        else:
            spp = self.mode["reference_spp"]
            for h in range(2):
                self.log(f"{name}: reference half {h + 1}/2 with our path tracer ({spp} spp)")
                half, _ = self.render(scene, "path", spp=spp, seed=1000 + h, tag=f"reference{h}")
                halves.append(metrics.read_rgb(half))
            made_by = f"gdmlt path tracer (no Mitsuba importable), 2 x {spp} spp, seeds 1000/1001"
        image = 0.5 * (halves[0] + halves[1])
        metrics.write_rgb(exr, image)
        meta = dict(wanted, made_by=made_by, noise_rel_mse=reference_noise(*halves),
                    made=time.strftime("%Y-%m-%d %H:%M:%S"))
        with open(meta_path, "w") as f:
            json.dump(meta, f, indent=1)
        self.log(f"{name}: reference {exr}, its own noise relMSE ~{meta['noise_rel_mse']:.2g}")
        self.references[name] = (image, dict(meta, path=exr))
        self.data["references"][name] = self.references[name][1]
        return self.references[name]

    def score(self, scene, exr, layer=""):
        reference, _ = self.reference(scene)
        image = metrics.read_rgb(exr, layer)
        return {"rel_mse": metrics.rel_mse(image, reference), "mean_ratio": float(image.mean() / reference.mean())}

    def save(self, fig, name):
        """Writes a figure beside the report; returns its name (the report links it)."""
        fig.tight_layout()
        fig.savefig(os.path.join(self.out, name), dpi=90)
        pyplot().close(fig)
        return name

    # ---- section 1 ----

    def equal_time(self):
        rows, runs = [], []
        renderers = list(INTEGRATORS) + ([MITSUBA] if self.runner is not None else [])
        for scene in self.scenes():
            self.reference(scene)
            if self.runner is not None:
                self.load_mitsuba(scene)
            for seconds in self.mode["times"]:
                for seed in range(self.mode["seeds"]):
                    for integrator in renderers:
                        if integrator == MITSUBA:
                            exr = os.path.join(self.runs_dir, f"{scene_name(scene)}_mitsuba_{seconds:g}s_s{seed}.exr")
                            info = self.runner.render(seconds, seed, exr)
                            run = {"render_s": info["seconds"], "rate": info["samples_per_s"], "stats": None}
                        else:
                            exr, stats = self.render(scene, integrator, seconds=seconds, seed=seed)
                            run = {"render_s": stats.get("render_s"), "rate": rate_of(integrator, stats),
                                   "what_ran": what_ran(stats), "stats": os.path.relpath(exr[:-4] + ".json", self.out)}
                        run.update(scene=scene_name(scene), integrator=integrator, budget_s=seconds, seed=seed,
                                   exr=os.path.relpath(exr, self.out), **self.score(scene, exr))
                        runs.append(run)
                        self.log(f"1 {scene_name(scene)} {integrator:7s} {seconds:g} s seed {seed}: relMSE "
                                 f"{run['rel_mse']:.4g} mean {run['mean_ratio']:.3f}")
        for scene in dict.fromkeys(r["scene"] for r in runs):
            for seconds in self.mode["times"]:
                group = {i: [r for r in runs if (r["scene"], r["integrator"], r["budget_s"]) == (scene, i, seconds)]
                         for i in renderers}
                mitsuba = median(r["rel_mse"] for r in group.get(MITSUBA, []))
                for integrator, sel in group.items():
                    rel = median(r["rel_mse"] for r in sel)
                    rows.append({"scene": scene, "budget_s": seconds, "integrator": integrator, "n": len(sel),
                                 "rel_mse": rel, "mean_ratio": median(r["mean_ratio"] for r in sel),
                                 "render_s": median(r["render_s"] for r in sel),
                                 "rate": median(r["rate"] for r in sel), "mitsuba_over_this": ratio(mitsuba, rel)})
        figures = [self.plot_curves(rows), self.plot_montage(runs)]
        table = md_table(["scene", "budget (s)", "integrator", "n", "relMSE", "mean", "time (s)", "rate (/s)",
                          "mitsuba/x"],
                         [[r["scene"], r["budget_s"], r["integrator"], r["n"], r["rel_mse"], r["mean_ratio"],
                           r["render_s"], r["rate"], r["mitsuba_over_this"]] for r in rows])
        scene0 = self.scenes()[0]
        text = [table, "",
                "relMSE, mean, time and rate: medians over seeds 0.." f"{self.mode['seeds'] - 1}. rate: samples/s "
                "(path, bdpt, gdpt, Mitsuba) or proposals per second of the chains (pssmlt, gdmlt). "
                "mitsuba/x > 1: x has the lower error at equal time. "
                + ("" if self.runner is not None else "Mitsuba 3 was not importable: no yardstick column."),
                "", f"![error vs time]({figures[0]})", "", f"![equal-time crops]({figures[1]})", "",
                "Reproduce one cell: `" + self.command_line(scene0, "gdmlt", ["--seed", "0"],
                                                          ["--time", f"{self.mode['times'][-1]:g}"]) + "`."]
        self.data["sections"]["1"] = {"runs": runs, "table": rows}
        return "\n".join(text)

    def plot_curves(self, rows):
        plt = pyplot()
        import matplotlib.ticker
        scenes = list(dict.fromkeys(r["scene"] for r in rows))
        fig, axes = plt.subplots(1, len(scenes), figsize=(4.2 * len(scenes), 3.6), squeeze=False)
        for ax, scene in zip(axes[0], scenes):
            for integrator in dict.fromkeys(r["integrator"] for r in rows):
                pts = [(r["budget_s"], r["rel_mse"]) for r in rows
                       if r["scene"] == scene and r["integrator"] == integrator and r["rel_mse"]]
                style = {"color": "black", "linestyle": "--"} if integrator == MITSUBA else {}
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker="o", label=integrator, **style)
            ax.set_xticks(self.mode["times"])
            ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_title(scene, fontsize=9)
            ax.set_xlabel("time budget (s)")
            ax.set_ylabel("relMSE")
            ax.grid(True, which="both", alpha=0.3)
        axes[0][0].legend(fontsize=7)
        return self.save(fig, "equal_time_curves.png")

    def plot_montage(self, runs):
        plt = pyplot()
        scenes = list(dict.fromkeys(r["scene"] for r in runs))
        budget = self.mode["times"][-1]
        renderers = list(dict.fromkeys(r["integrator"] for r in runs))
        fig, axes = plt.subplots(len(scenes), len(renderers) + 1,
                                 figsize=(1.9 * (len(renderers) + 1), 1.9 * len(scenes)), squeeze=False)
        for i, scene in enumerate(scenes):
            reference, _ = self.references[scene]
            h, w = reference.shape[:2]
            y0, x0, size = h // 4, w // 4, max(1, min(h, w) // 2)
            crop = (slice(y0, y0 + size), slice(x0, x0 + size))
            exposure = 0.5 / max(1e-6, float(np.median(reference[crop])) + 1e-6)
            panels = [("reference", reference)]
            for integrator in renderers:
                run = next(r for r in runs if (r["scene"], r["integrator"], r["budget_s"], r["seed"]) ==
                           (scene, integrator, budget, 0))
                panels.append((f"{integrator}\n{run['rel_mse']:.3g}", metrics.read_rgb(os.path.join(self.out, run["exr"]))))
            for ax, (label, image) in zip(axes[i], panels):
                ax.imshow(tonemap(image[crop], exposure), interpolation="nearest")
                ax.set_xticks([])
                ax.set_yticks([])
                ax.set_title(label, fontsize=7)
            axes[i][0].set_ylabel(scene, fontsize=7)
        fig.suptitle(f"centre crops at {budget:g} s, seed 0 (relMSE of the whole image)", fontsize=8)
        return self.save(fig, "equal_time_crops.png")

    # ---- section 2 ----

    def knob_scene(self):
        names = [scene_name(s) for s in self.scenes()]
        wanted = self.args.knob_scene or ("cbox_glass_sphere" if "cbox_glass_sphere" in names else names[0])
        return self.resolve_scene(wanted)

    def knobs(self):
        scene = self.knob_scene()
        seconds = self.mode["knob_time"]
        groups = [
            ("shift family", [("auto", []), ("reconnect", ["--shift", "reconnect"]),
                              ("halfvector", ["--shift", "halfvector"]), ("replay", ["--shift", "replay"])]),
            ("primal weight w", [("1 (default)", []), ("0.25", ["--primal-weight", "0.25"]),
                                 ("4", ["--primal-weight", "4"])]),
            ("budget split", [("auto (default)", []), ("chains only", ["--gdpt-share", "0"]),
                              ("half GDPT", ["--gdpt-share", "0.5"]), ("GDPT only", ["--gdpt-share", "1"])]),
            ("large-step probability", [("0.7 (default)", []), ("0.3", ["--p-large", "0.3"])]),
            ("mutation size S1,S2", [("1/1024,1/64 (default)", []),
                                     ("1/256,1/16", ["--mutation-size", "0.00390625", "0.0625"])]),
            ("neighbours", [("lattice (default)", []), ("adap K=4", ["--neighbours", "adap"]),
                            ("adap K=2", ["--neighbours", "adap", "--adap-k", "2"]),
                            ("adap K=8", ["--neighbours", "adap", "--adap-k", "8"]),
                            ("adap bandwidths x0.5", ["--neighbours", "adap", "--adap-sigma", "0.05", "0.1", "0.025",
                                                      "0.25"]),
                            ("adap bandwidths x2", ["--neighbours", "adap", "--adap-sigma", "0.2", "0.4", "0.1", "1"]),
                            ("adap, target not normalised by link count",
                             ["--neighbours", "adap", "--normalise-link-count", "false"])]),
            ("samples", [("auto (default)", []), ("unidirectional", ["--bidirectional", "false"]),
                         ("bidirectional", ["--bidirectional", "true"])]),
            ("light tracing (bidirectional)", [("from a pass, share 0.3", ["--bidirectional", "true"]),
                                               ("from the chains", ["--bidirectional", "true",
                                                                    "--light-tracing-pass", "false"]),
                                               ("from a pass, share 0.5", ["--bidirectional", "true",
                                                                           "--light-tracing-share", "0.5"])]),
        ]
        rows, default_raw = [], None
        for group, variants in groups:
            for label, extra in variants:
                runs = []
                for seed in range(self.mode["knob_seeds"]):
                    tag = "knob_" + "_".join(a.lstrip("-") for a in extra) if extra else "knob_default"
                    exr, stats = self.render(scene, "gdmlt", extra, seconds=seconds, seed=seed, tag=tag)
                    if not extra and seed == 0:
                        default_raw = exr
                    run = dict(self.score(scene, exr), rate=rate_of("gdmlt", stats), render_s=stats.get("render_s"),
                               shift_ok=what_ran(stats)["shift_ok_rate"])
                    runs.append(run)
                row = {"knob": group, "setting": label, "args": " ".join(extra), "n": len(runs),
                       **{k: median(r[k] for r in runs) for k in ("rel_mse", "mean_ratio", "rate", "render_s", "shift_ok")}}
                rows.append(row)
                self.log(f"2 {group}: {label}: relMSE {row['rel_mse']:.4g} mean {row['mean_ratio']:.3f} "
                         f"{fmt(row['rate'])} proposals/s")
        for group in dict.fromkeys(r["knob"] for r in rows):
            first = next(r for r in rows if r["knob"] == group)
            for r in rows:
                if r["knob"] == group:
                    r["rate_vs_default"] = ratio(r["rate"], first["rate"])
        recon = self.reconstruction_knobs(scene, default_raw)
        manifold = self.manifold_knobs()
        figure = self.plot_knobs(rows, recon)
        text = [f"GDMLT on `{scene_name(scene)}` at {seconds:g} s (medians of {self.mode['knob_seeds']} seeds); "
                "rate: proposals per second of the chains, also as a ratio to the default (the time side of "
                "the price: at equal time a slower setting runs fewer proposals). Each group renders its default again: the "
                "spread of those rows is the run-to-run noise a setting's difference must beat.", "",
                md_table(["knob", "setting", "relMSE", "mean", "proposals/s", "rate / default", "shift ok"],
                         [[r["knob"], r["setting"], r["rel_mse"], r["mean_ratio"], r["rate"], r["rate_vs_default"],
                           r["shift_ok"]] for r in rows]), "",
                "Reproduce a row: `" + self.command_line(scene, "gdmlt", ["--primal-weight", "4"], ["--time", f"{seconds:g}"])
                + "` (the row's arguments in place of `--primal-weight 4`).", "",
                "Reconstruction, offline on the default render's raw layers (`gdmlt reconstruct RAW.exr --method M "
                "--alpha A --iterations N`; solve seconds from its summary line):", "",
                md_table(["method", "alpha", "iterations", "relMSE", "mean", "solve (s)"],
                         [[r["method"], r["alpha"], r["iterations"], r["rel_mse"], r["mean_ratio"], r["solve_s"]]
                          for r in recon]), "",
                f"![knobs]({figure})", "",
                "Manifold walk (bench_manifold: synthetic specular chains; time per walk against the relative "
                "tolerance and the iteration cap): `build/release/bench/bench_manifold`", "",
                md_table(["benchmark", "time per walk (us)", "success rate", "iterations per walk"],
                         [[m["name"], m["us"], m["success_rate"], m["mean_iterations"]] for m in manifold])]
        self.data["sections"]["2"] = {"scene": scene_name(scene), "gdmlt": rows, "reconstruction": recon,
                                      "manifold": manifold}
        return "\n".join(text)

    def reconstruct(self, raw, args, tag):
        out = raw[:-4] + f"_{tag}.exr"
        proc = subprocess.run([self.args.binary, "reconstruct", raw, "-o", out, "-t", str(self.args.threads)] + args,
                              check=True, capture_output=True, text=True)
        solve, setup = parse_reconstruct_seconds(proc.stdout + proc.stderr)
        return out, solve + setup

    def reconstruction_knobs(self, scene, raw):
        variants = [("l1", a, n) for a in (0.01, 0.05, 0.2) for n in (None,)] + \
                   [("l1", 0.05, n) for n in (5, 50)] + [("l2", 0.05, None), ("cv", None, None)]
        rows = []
        for method, alpha, iterations in variants:
            args = ["--method", method] + (["--alpha", str(alpha)] if alpha is not None else []) + \
                   (["--iterations", str(iterations)] if iterations else [])
            tag = "_".join(a.lstrip("-") for a in args)
            out, seconds = self.reconstruct(raw, args, tag)
            rows.append({"method": method, "alpha": alpha, "iterations": iterations or "default",
                         "solve_s": seconds, **self.score(scene, out)})
        return rows

    def manifold_knobs(self):
        rows = []
        for b in self.run_benchmark("bench_manifold"):
            rows.append({"name": re.sub(r"/min_time:[0-9.]+", "", b["name"]), "us": b["real_time"] * {"ns": 1e-3, "us": 1.0, "ms": 1e3}[b["time_unit"]],
                         "success_rate": b.get("success_rate"), "mean_iterations": b.get("mean_iterations")})
        self.log(f"2 bench_manifold: {len(rows)} settings")
        return rows

    def plot_knobs(self, rows, recon):
        plt = pyplot()
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        ax = axes[0]
        for group in dict.fromkeys(r["knob"] for r in rows):
            sel = [r for r in rows if r["knob"] == group and r["rate"] and r["rel_mse"]]
            ax.scatter([1.0 / r["rate"] * 1e6 for r in sel], [r["rel_mse"] for r in sel], label=group)
            for r in sel:
                ax.annotate(r["setting"].split(" (")[0], (1.0 / r["rate"] * 1e6, r["rel_mse"]), fontsize=6)
        ax.set_xlabel("time per proposal (us)")
        ax.set_ylabel("relMSE at equal time")
        ax.set_title("GDMLT knobs: cost and error", fontsize=9)
        ax.legend(fontsize=6)
        ax.grid(True, alpha=0.3)
        ax = axes[1]
        ax.scatter([r["solve_s"] for r in recon], [r["rel_mse"] for r in recon])
        for r in recon:
            ax.annotate(f"{r['method']} a={r['alpha']} n={r['iterations']}", (r["solve_s"], r["rel_mse"]), fontsize=6)
        ax.set_xlabel("solve time (s)")
        ax.set_ylabel("relMSE")
        ax.set_title("reconstruction settings on one raw render", fontsize=9)
        ax.grid(True, alpha=0.3)
        return self.save(fig, "knobs.png")

    # ---- section 3 ----

    def shift_table(self):
        rows = []
        spp = self.mode["shift_spp"]
        for scene in self.scenes():
            self.reference(scene)
            _, path_stats = self.render(scene, "path", spp=spp, seed=0, tag="shiftbase")
            path_rate = path_stats.get("samples_per_s")
            env = {"GDMLT_BENCH_SCENE": scene,
                   "GDMLT_BENCH_DEFINES": ",".join(f"{k}={v}" for k, v in self.defines.items())}
            bench = {b["name"].split("/")[-1]: b for b in self.run_benchmark("bench_shifts", env)}
            # The independent estimate the differences are checked against (seed 1; section 4
            # reconstructs the same render).
            independent, _ = self.independent_gdpt(scene)
            primal_b = metrics.read_luminance(independent, "primal")
            variance_b = metrics.read_luminance(independent, "primal_variance")
            for family in SHIFT_FAMILIES:
                exr, stats = self.render(scene, "gdpt", ["--shift", family], spp=spp, seed=0, tag=f"shift_{family}")
                lum = {name: metrics.read_luminance(exr, name) for name in
                       ("primal_variance", "dx", "dx_variance", "dy", "dy_variance")}
                errors = [gradient_error_ratio(lum["dx"], lum["dx_variance"], primal_b, variance_b, 1),
                          gradient_error_ratio(lum["dy"], lum["dy_variance"], primal_b, variance_b, 0)]
                b = bench.get(family, {})
                row = {"scene": scene_name(scene), "family": family,
                       "similarity": difference_variance_ratio(lum["primal_variance"],
                                                               [lum["dx_variance"], lum["dy_variance"]]),
                       "error_ratio": median(errors),
                       "round_trip": b.get("round_trip_rate"), "success": b.get("success_rate"),
                       "ns_per_shift": b.get("real_time") * {"ns": 1, "us": 1e3, "ms": 1e6}[b["time_unit"]] if b else None,
                       "shifts_per_sample": (stats.get("shifts", {}).get("total", 0) /
                                             max(1, stats.get("samples", 0) or 1)) if stats.get("samples") else None,
                       "sample_cost_vs_path": ratio(path_rate, stats.get("samples_per_s")),
                       **{f"final_{k}": v for k, v in self.score(scene, exr).items()}}
                rows.append(row)
                self.log(f"3 {row['scene']} {family}: similarity {fmt(row['similarity'])}, err^2/var {fmt(row['error_ratio'])}, "
                         f"round trip {fmt(row['round_trip'])}, {fmt(row['ns_per_shift'])} ns/shift")
        figure = self.plot_shifts(rows)
        text = [f"GDPT at {spp} spp per family (seed 0), and bench_shifts on the same scene file "
                "(`GDMLT_BENCH_SCENE=SCENE build/release/bench/bench_shifts`: 1024 camera paths, each shifted "
                "one pixel right, untimed round trip back).", "",
                "- similarity: summed variance of the differences / summed variance of the primal (per "
                "direction): 2 = uncorrelated offsets, 0 = perfectly correlated; lower is better.",
                "- correctness: squared error of the differences against the pixel differences of an "
                "independent path-traced estimate (the primal of a GDPT render with seed 1: its base paths "
                "are path tracing's), over the sum of the variances both renders estimated (sums over edges, "
                "median of dx and dy): 1 = unbiased within the noise of this many samples, a bias makes it "
                "larger, more so with more samples. (Not against the reference: its pixel noise would "
                "swamp differences that have far less.)",
                "- invertibility: round trips / successful shifts; efficiency: time per shift and success rate "
                "(bench_shifts), sample cost = path samples/s / GDPT samples/s in this run.", "",
                md_table(["scene", "family", "similarity", "err^2 / var", "round trip", "success", "ns / shift",
                          "sample cost / path", "final relMSE", "mean"],
                         [[r["scene"], r["family"], r["similarity"], r["error_ratio"], r["round_trip"], r["success"],
                           r["ns_per_shift"], r["sample_cost_vs_path"], r["final_rel_mse"], r["final_mean_ratio"]]
                          for r in rows]), "", f"![shift families]({figure})", "",
                "Reproduce a row: `" + self.command_line(self.scenes()[0], "gdpt", ["--shift", "replay"],
                                                         ["--spp", str(spp)]) + "`."]
        self.data["sections"]["3"] = {"spp": spp, "rows": rows}
        return "\n".join(text)

    def independent_gdpt(self, scene):
        """GDPT (auto shift, seed 1) at the shift table's spp: the independent primal of section 3
        and the raw render of section 4."""
        if scene not in self.independent:
            self.independent[scene] = self.render(scene, "gdpt", spp=self.mode["shift_spp"], seed=1, tag="independent")
        return self.independent[scene]

    def plot_shifts(self, rows):
        plt = pyplot()
        scenes = list(dict.fromkeys(r["scene"] for r in rows))
        fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
        width = 0.8 / len(SHIFT_FAMILIES)
        for k, (key, label) in enumerate((("similarity", "similarity (lower: better)"),
                                          ("success", "success rate"), ("ns_per_shift", "ns per shift"))):
            ax = axes[k]
            for j, family in enumerate(SHIFT_FAMILIES):
                values = [next((r[key] for r in rows if r["scene"] == s and r["family"] == family), None) or 0
                          for s in scenes]
                ax.bar(np.arange(len(scenes)) + j * width, values, width, label=family)
            ax.set_xticks(np.arange(len(scenes)) + 0.4 - width / 2)
            ax.set_xticklabels(scenes, rotation=20, fontsize=6)
            ax.set_title(label, fontsize=9)
        axes[0].legend(fontsize=6)
        return self.save(fig, "shift_families.png")

    # ---- section 4 ----

    def reconstruction_table(self):
        import OpenImageIO as oiio
        rng = np.random.default_rng(7)
        rows = []
        spp = self.mode["shift_spp"]
        for scene in self.scenes():
            raw, _ = self.independent_gdpt(scene)
            # The same render with 0.1% of the pixels of each of primal, dx and dy given a spike of
            # 100x the layer's mean magnitude (independent fireflies; seed 7).
            buf = oiio.ImageBuf(raw)
            names = list(buf.spec().channelnames)
            pixels = np.array(buf.get_pixels(oiio.FLOAT))
            for layer in ("primal", "dx", "dy"):
                idx = [names.index(f"{layer}.{c}") for c in "RGB"]
                pixels[:, :, idx] = inject_outliers(pixels[:, :, idx], 1e-3, 100.0, rng)
            spiked = raw[:-4] + "_outliers.exr"
            out = oiio.ImageBuf(buf.spec())
            out.set_pixels(oiio.ROI(), pixels.astype(np.float32))
            if not out.write(spiked):
                raise RuntimeError(out.geterror())
            reference, _ = self.reference(scene)
            for method in RECONSTRUCTIONS:
                row = {"scene": scene_name(scene), "method": method}
                for source, key in ((raw, "clean"), (spiked, "outliers")):
                    if method == "primal":
                        image = metrics.read_rgb(source, "primal") + metrics.read_rgb(source, "very_direct")
                    else:
                        args = {"l1": ["--method", "l1", "--huber", "0"], "huber": ["--method", "l1", "--huber", "1.345"],
                                "l2": ["--method", "l2"], "cv": ["--method", "cv"]}[method]
                        final, _ = self.reconstruct(source, args, f"{method}")
                        image = metrics.read_rgb(final)
                    row[f"{key}_rel_mse"] = metrics.rel_mse(image, reference)
                    if key == "clean":
                        row["mean_ratio"] = float(image.mean() / reference.mean())
                        row["low_pass_rel_mse"] = metrics.low_pass_rel_mse(image, reference) \
                            if min(image.shape[:2]) >= 8 else None
                row["outlier_factor"] = ratio(row["outliers_rel_mse"], row["clean_rel_mse"])
                rows.append(row)
                self.log(f"4 {row['scene']} {method}: relMSE {row['clean_rel_mse']:.4g} -> {row['outliers_rel_mse']:.4g} "
                         f"with outliers, mean {row['mean_ratio']:.3f}")
        timing = self.reconstruction_timing()
        res = self.args.timing_res
        size = f"{res}x{res}" + (" (921,600 pixels, 1280x720's count)" if res == 960 else "")
        text = [f"Efficiency: `gdmlt reconstruct` of a GDPT raw render of `{scene_name(self.knob_scene())}` at {size}, "
                f"{self.args.threads} threads, solve + setup seconds from its summary line (median of "
                f"{self.mode['reconstruct_repeats']}):", "",
                md_table(["method", "seconds", "ms"], [[t["method"], t["seconds"], 1e3 * t["seconds"]] for t in timing]),
                "", f"Robustness and bias: GDPT at {spp} spp (seed 1) on each scene, reconstructed by each method, "
                "then the same raw layers with 0.1% of the pixels of primal, dx and dy spiked (100x the layer's "
                "mean magnitude; numpy seed 7). primal = no reconstruction (primal + very_direct); l1 = pure L1; "
                "huber = L1 with Huber rows (the render default); low-pass = relMSE after 8x8 box averaging "
                "(coarse error: bias and lost energy, not pixel noise).", "",
                md_table(["scene", "method", "relMSE", "mean", "low-pass relMSE", "relMSE with outliers",
                          "outlier factor"],
                         [[r["scene"], r["method"], r["clean_rel_mse"], r["mean_ratio"], r["low_pass_rel_mse"],
                           r["outliers_rel_mse"], r["outlier_factor"]] for r in rows]), "",
                "Reproduce: `" + self.command_line(self.scenes()[0], "gdpt", ["-o", "raw.exr"], ["--spp", str(spp)])
                + "` then `gdmlt reconstruct raw.exr --method l2 -o final.exr`."]
        self.data["sections"]["4"] = {"timing": timing, "timing_resolution": self.args.timing_res, "rows": rows}
        return "\n".join(text)

    def reconstruction_timing(self):
        scene = self.knob_scene()
        saved = dict(self.defines)
        self.defines = dict(saved, res=str(self.args.timing_res))
        try:
            raw, _ = self.render(scene, "gdpt", spp=1, seed=2, tag="recon960")
        finally:
            self.defines = saved
        rows = []
        for method in ("l1", "l2", "cv"):
            times = [self.reconstruct(raw, ["--method", method], method)[1]
                     for _ in range(self.mode["reconstruct_repeats"])]
            rows.append({"method": method, "seconds": statistics.median(times)})
            self.log(f"4 timing {method} at {self.args.timing_res}^2: {rows[-1]['seconds']:.3f} s")
        return rows

    # ---- section 5 ----

    def adap(self):
        names = [scene_name(s) for s in self.scenes()]
        wanted = [n for n in ("rough_metal_glass", "cbox_glass_sphere", "materials_envmap") if n in names] or names[:1]
        rows, picture_raw = [], None
        for name in wanted:
            scene = self.resolve_scene(name)
            for seconds in self.mode["adap_times"]:
                for integrator in ("gdpt", "gdmlt"):
                    results = {}
                    for neighbours in ("lattice", "adap"):
                        runs = []
                        for seed in range(self.mode["knob_seeds"]):
                            exr, stats = self.render(scene, integrator, ["--neighbours", neighbours], seconds=seconds,
                                                     seed=seed, tag=f"nb_{neighbours}")
                            if neighbours == "adap" and picture_raw is None:
                                picture_raw = exr
                            runs.append(dict(self.score(scene, exr), rate=rate_of(integrator, stats),
                                             adap_s=adap_seconds(stats)))
                        results[neighbours] = {k: median(r[k] for r in runs) for k in runs[0]}
                    row = {"scene": name, "budget_s": seconds, "integrator": integrator,
                           **{f"{n}_{k}": v for n, res in results.items() for k, v in res.items()}}
                    row["lattice_over_adap"] = ratio(row["lattice_rel_mse"], row["adap_rel_mse"])
                    rows.append(row)
                    self.log(f"5 {name} {integrator} {seconds:g} s: lattice {row['lattice_rel_mse']:.4g} adap "
                             f"{row['adap_rel_mse']:.4g}")
        figure = None
        if picture_raw is not None:
            figure = "adap_edges.png"
            subprocess.run([sys.executable, os.path.join(HERE, "adap_edges.py"), picture_raw, "-o",
                            os.path.join(self.out, figure)], check=True, capture_output=True)
        text = [f"Medians of {self.mode['knob_seeds']} seeds; lattice/adap > 1: ADAP has the lower error. adap time: "
                "the feature pass and the selection, counted in the budget.", "",
                md_table(["scene", "budget (s)", "integrator", "lattice relMSE", "mean", "adap relMSE", "mean",
                          "lattice/adap", "adap time (s)"],
                         [[r["scene"], r["budget_s"], r["integrator"], r["lattice_rel_mse"], r["lattice_mean_ratio"],
                           r["adap_rel_mse"], r["adap_mean_ratio"], r["lattice_over_adap"], r["adap_adap_s"]]
                          for r in rows]), "",
                (f"![ADAP edges]({figure}) (`bench/adap_edges.py {os.path.relpath(picture_raw, self.out)}`: lattice "
                 "edges grey, longer ones orange, dropped lattice edges red)") if figure else "", "",
                "Reproduce: `" + self.command_line(self.resolve_scene(wanted[0]), "gdmlt", ["--neighbours", "adap"],
                                                   ["--time", f"{self.mode['adap_times'][0]:g}"]) + "`."]
        self.data["sections"]["5"] = {"rows": rows}
        return "\n".join(text)

    # ---- section 6 ----

    def what_ran_section(self):
        runs = [r for r in self.data["sections"].get("1", {}).get("runs", []) if r.get("what_ran")]
        budget = self.mode["times"][-1]
        rows = []
        for r in runs:
            if r["budget_s"] != budget or r["seed"] != 0:
                continue
            w = r["what_ran"]
            rows.append({"scene": r["scene"], "integrator": r["integrator"], **{k: v for k, v in w.items()
                                                                              if k != "time_shares"},
                         **{f"share_{k}": v for k, v in w["time_shares"].items()}})
        figure = self.plot_shares(rows)
        text = [f"From the stats JSON of section 1's renders at {budget:g} s (seed 0). manifold: the manifold solver "
                "was in play (walks counted), shifts: offset paths were built, LT: light tracing, chains: Markov "
                "chains. Shares: the stage's seconds over render_s (the rest is sampling).", "",
                md_table(["scene", "integrator", "manifold", "walks", "Newton its", "shifts", "shift ok", "LT",
                          "chains", "rays", "non-finite dropped", "bootstrap", "very direct", "LT pass",
                          "reconstruct"],
                         [[r["scene"], r["integrator"], r["manifold_solver"], r["manifold_walks"],
                           r["manifold_iterations"], r["shifts"], r["shift_ok_rate"], r["light_tracing"],
                           r["markov_chains"], r["rays"], r["nonfinite_dropped"], r.get("share_bootstrap_s"),
                           r.get("share_very_direct_s"), r.get("share_light_tracing_s"),
                           r.get("share_reconstruct_s")] for r in rows]), "",
                "Why the manifold solver is (not) in play, per scene (gdmlt's stats):", ""]
        for r in rows:
            if r["integrator"] == "gdmlt":
                text.append(f"- {r['scene']}: {r['why']}")
        text += ["", f"![time shares]({figure})"]
        self.data["sections"]["6"] = {"rows": rows}
        return "\n".join(text)

    def plot_shares(self, rows):
        plt = pyplot()
        labels = [f"{r['scene']}\n{r['integrator']}" for r in rows]
        fig, ax = plt.subplots(figsize=(max(6, 0.45 * len(rows)), 3.6))
        bottom = np.zeros(len(rows))
        for stage in STAGES:
            values = np.array([r.get(f"share_{stage}") or 0.0 for r in rows])
            ax.bar(range(len(rows)), values, bottom=bottom, label=stage[:-2])
            bottom += values
        ax.bar(range(len(rows)), np.clip(1 - bottom, 0, 1), bottom=bottom, label="sampling", color="lightgrey")
        ax.set_xticks(range(len(rows)))
        ax.set_xticklabels(labels, rotation=90, fontsize=5)
        ax.set_ylabel("share of render time")
        ax.legend(fontsize=6)
        return self.save(fig, "time_shares.png")

    # ---- report ----

    def run(self):
        """Runs the sections and writes the report. Ctrl-C (or a failing section) still writes
        the report of the sections that finished, saying where it stopped; the exit status is
        then 130 (or the failure is raised again)."""
        self.start_mitsuba()
        sections, stopped, failure = {}, None, None
        try:
            steps = [(1, self.equal_time), (2, self.knobs), (3, self.shift_table), (4, self.reconstruction_table),
                     (5, self.adap), (6, self.what_ran_section)]
            wanted = set(self.args.sections or SECTION_TITLES)
            if 6 in wanted:
                wanted.add(1)  # what ran is read from section 1's renders
            for number, step in steps:
                if number not in wanted:
                    continue
                self.log(f"section {number}: {SECTION_TITLES[number]}")
                try:
                    sections[number] = step()
                except (KeyboardInterrupt, Exception) as e:  # noqa: B902 - reported, then re-raised
                    # Ctrl-C reaches gdmlt too, which stops and exits 130: either may arrive first.
                    if isinstance(e, subprocess.CalledProcessError) and e.returncode in (130, -2):
                        e = KeyboardInterrupt()
                    stopped = (f"interrupted (Ctrl-C) during section {number}" if isinstance(e, KeyboardInterrupt)
                               else f"section {number} failed: {type(e).__name__}: {e}")
                    failure = e
                    break
        finally:
            if self.runner is not None:
                self.mitsuba_info = dict(self.mitsuba_info, variant=self.runner.info.get("variant"))
                self.runner.close()
        self.data["mitsuba"] = self.mitsuba_info
        self.data["elapsed_s"] = time.perf_counter() - self.started
        self.data["stopped"] = stopped
        report = self.report(sections, stopped)
        with open(os.path.join(self.out, "report.md"), "w") as f:
            f.write(report)
        with open(os.path.join(self.out, "study.json"), "w") as f:
            json.dump(self.data, f, indent=1, default=float)
            f.write("\n")
        self.log(f"report: {os.path.join(self.out, 'report.md')}" + (f" ({stopped})" if stopped else ""))
        if isinstance(failure, KeyboardInterrupt):
            raise SystemExit(130)
        if failure is not None:
            raise failure

    def report(self, sections, stopped=None):
        version = subprocess.run([self.args.binary, "--version"], capture_output=True, text=True).stdout.strip()
        mi = self.mitsuba_info
        yardstick = (f"Mitsuba {mi.get('version')} ({mi.get('variant')}, {self.args.threads} threads) in the same run"
                     if "version" in mi else f"none ({mi.get('error') or mi.get('skipped')})")
        lines = ["# gdmlt: what accuracy costs in time", "",
                 f"`{self.data['settings']['command']}` ({self.data['settings']['mode']} mode), gdmlt {version}, "
                 f"{os.cpu_count()} cores, {self.args.threads} threads, {self.data['elapsed_s'] / 60:.1f} minutes. "
                 f"Yardstick: {yardstick}. Defines: {self.defines or 'none'}.", "",
                 "Times are this machine's at this moment: compare rows within this report, or through the "
                 "mitsuba/x ratios across machines.", ""]
        if stopped:
            lines += [f"**Incomplete: {stopped}.** The sections below are those that finished.", ""]
        lines += ["References:", ""]
        for name, info in self.data["references"].items():
            noise = info.get("noise_rel_mse")
            lines.append(f"- {name}: {info.get('made_by') or info.get('source')}"
                         + (f", own noise relMSE ~{noise:.2g}" if noise is not None else ""))
        mode = "--quick " if self.args.quick else ""
        for number in sorted(sections):
            lines += ["", f"## {number}. {SECTION_TITLES[number]}", "", sections[number], "",
                      f"This section alone: `bench/study.py {mode}--sections {number}`."]
        return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="about 10 minutes instead of hours")
    ap.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    ap.add_argument("--bench-dir", help="Google Benchmark executables (default: bench/ beside --binary)")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "study"))
    ap.add_argument("--reference-cache", default=os.path.join(ROOT, "bench", "out", "references"))
    ap.add_argument("--scenes", nargs="+", help="scene names or .xml paths (default: every scenes/*.xml)")
    ap.add_argument("--knob-scene", help="scene of section 2 (default cbox_glass_sphere)")
    ap.add_argument("--times", nargs="+", type=float, help="budgets of section 1 (the last also for 2 and 5)")
    ap.add_argument("--seeds", type=int, help="repeats per configuration")
    ap.add_argument("--sections", nargs="+", type=int, choices=range(1, 7), help="only these sections")
    ap.add_argument("--reference-spp", type=int, help="spp per half of our own path-traced references")
    ap.add_argument("--reference-s", type=float, help="seconds per half of Mitsuba references")
    ap.add_argument("-D", "--define", action="append", default=[], help="scene define name=value (all renders)")
    ap.add_argument("--bench-min-time", type=float, help="Google Benchmark --benchmark_min_time")
    ap.add_argument("--timing-res", type=int, default=960,
                    help="side of the square render whose reconstruction is timed (960^2 = 1280x720's pixels)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--mitsuba-python", default=sys.executable,
                    help="interpreter that can import mitsuba (e.g. a venv with `pip install mitsuba`)")
    args = ap.parse_args(argv)
    args.binary = os.path.abspath(args.binary)
    args.bench_dir = os.path.abspath(args.bench_dir or os.path.join(os.path.dirname(args.binary), "bench"))
    if not os.path.isfile(args.binary):
        raise SystemExit(f"gdmlt not found: {args.binary} (run the README's first command)")
    for d in args.define:
        if "=" not in d:
            raise SystemExit(f"--define {d!r}: expected name=value")
    Study(args).run()


if __name__ == "__main__":
    main()
