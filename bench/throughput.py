#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Path-tracer throughput: samples/s, rays/s, the share of Embree, Mitsuba 3 for scale, and the
MLT and gradient-domain integrators' rates against the path tracer's.

A benchmark, not a test: it builds nothing and asserts nothing. It prints

1. samples/s and rays/s of `gdmlt render` (median, min and max over --runs renders of
   the scene at max_depth, spp, resolution and thread count given), read from the `--stats`
   JSON the CLI writes (render time only: scene loading and image output are excluded);
2. the fraction of the path tracer's work spent inside Embree (see "Embree fraction" below),
   and raw Embree's own rate on the same scene (see "Raw Embree");
3. when Mitsuba 3 can be imported (by this interpreter or by --mitsuba-python), Mitsuba's
   samples/s on the same scene file with the same resolution, spp, max_depth and thread
   count, rendered in the same run and interleaved with ours (one of theirs after each of
   ours, so that a change of machine load hits both), and the ratio gdmlt / Mitsuba;
4. for each integrator of --integrators (default pssmlt, gdpt, gdmlt), its rate against the
   path tracer's samples/s on the same scene (see "Other integrators' rates").

Embree fraction
---------------
Method "callgrind" (default): one render at a small resolution (--profile-res, 1 thread) under
`valgrind --tool=callgrind`; then, from `callgrind_annotate --inclusive=yes`,

    fraction = sum of inclusive Ir of the Embree query entry points (rtcIntersect*,
               rtcOccluded*; everything Embree does below them is included)
               / inclusive Ir of gdmlt::render_path (the whole render loop: cameras,
               shading, sampling, film, TBB; scene loading, the BVH build and image output
               are outside it and therefore excluded).

Instruction counts are repeatable to the instruction on a shared machine, which wall-clock
timings are not, so optimisations are decided on them. They are not time: Embree's
SIMD traversal retires fewer, wider instructions than most of our code, and valgrind has no
AVX-512, so the counts are of the AVX2 build of our own SIMD kernels (core/math/simd.h).

Method "perf": `perf record -e cpu-clock` (a software clock: works without hardware counters)
over one full-size render at the requested thread count; fraction = samples in libembree /
samples in everything except the dynamic loader and the kernel (start-up is mostly symbol
relocation of the image libraries, which would otherwise dilute the share). This is a share of
time, with sampling noise of about 1/sqrt(samples).

"both" runs the two; "none" skips the measurement.

Raw Embree
----------
`bench_embree` (Google Benchmark, built beside gdmlt) traces camera, bounce (cosine about the
normal) and shadow rays precomputed on the same scene and resolution through the same Embree
calls as the renderer, at the same thread count, and gives rays/s per kind, for single rays
(rtcIntersect1/rtcOccluded1, BM_Embree) and for packets of 16 (rtcIntersect16/rtcOccluded16,
BM_Embree_packet, the path tracer's wavefront's calls). The path tracer's rays of each run, at
those rates, would take T_raw seconds; the line "path tracer at X of raw Embree" gives
T_raw / render_s (median over runs) at the single-ray rates: the share of the render an
Embree-only renderer would still need, i.e. our rays/s over raw Embree's for the same ray mix.
The same share at the packet rates follows it (lower where packets are faster). The wavefront
traces its camera rays as it takes them, a pixel's samples in a row, in packets flagged coherent
(Accelerator::intersect_packet); so the packet rate for camera rays is bench_embree's
BM_Embree_packet/camera_pixel_coherent (one pixel's rays per packet, flagged coherent), not the
packets of camera rays through random film positions (BM_Embree_packet/camera, also printed).

Other integrators' rates
------------------------
In each run, after the path tracer (and Mitsuba's render), each integrator of --integrators
renders the same scene once with the same resolution, max_depth, thread count and seed, and as
much work as the path tracer: `--spp SPP` for gdpt, `--mpp SPP` (mutations per pixel; --spp too)
for pssmlt and gdmlt. Its rate is divided by that run's path tracer samples/s, so both were
measured under the same machine load; the median over runs of that ratio is reported. The rates
are these fields of the `--stats` JSON:

    pssmlt  mutations_per_s = mutations / chains_s: the Markov chains only; the bootstrap that
            estimates the normalisation b (bootstrap_s: 100000 independent path samples, at
            least 10 per chain, whatever the image size) and a separate direct pass (direct_s,
            off by default) are excluded;
    gdpt    samples_per_s = samples / sampling_s (samples = pixels x spp, each a base path and
            its shifts to the pixel's lattice neighbours): the reconstruction (reconstruct_s) is
            excluded;
    gdmlt   proposals_per_s = mutations / chains_s (one proposal: a base path and its shifts;
            the same number as its mutations_per_s): the Markov chains only; the bootstrap
            (bootstrap_s: from 100000 samples, grown up to 16x until b's relative standard
            error is below 1%), the very direct pass (very_direct_s), a light tracing pass
            (light_tracing_s, bidirectional only) and the reconstruction (reconstruct_s) are
            excluded.

The path tracer's samples/s is samples / render_s (its whole render loop). The excluded phases'
times are printed beside the rates (their medians over runs); at small images or low budgets the
bootstrap can take longer than the chains, so a rate over render_s would be far lower. For scale:
in Mitsuba 0.6, PSSMLT ran at 0.45x its path tracer's samples/s, and gradient-mts's G-PT at 0.26x.

Mitsuba
-------
Mitsuba runs in a child process (the interpreter given by --mitsuba-python, default this one),
so the script itself needs only the standard library. The `llvm_ad_*` variants need an LLVM
>= 16 shared library; if DRJIT_LIBLLVM_PATH is unset, the newest /usr/lib/*/libLLVM-NN.so with
NN >= 16 is used (Debian 12: `apt-get install libllvm19`). When the requested variant cannot be
set, scalar_rgb is used instead and the output says so. The first Mitsuba render (JIT
compilation, kernel cache) is a warm-up and not timed. Mitsuba's time is that of mi.render()
until the image is evaluated, which like ours excludes scene loading.

Example:
    /usr/bin/python3 bench/throughput.py --gdmlt build/release/gdmlt --runs 5 \\
        --mitsuba-python /tmp/mi_venv/bin/python
    /usr/bin/python3 bench/throughput.py --integrators none      # the path tracer only
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

MITSUBA_WORKER = r"""
import json, sys, time
try:
    import drjit as dr
    import mitsuba as mi
except Exception as e:  # reported to the parent, which then skips the comparison
    print(json.dumps({"error": "import failed: %s" % e}), flush=True)
    sys.exit(0)
cfg = json.loads(sys.argv[1])
variant, note = cfg["variant"], ""
try:
    mi.set_variant(variant)
except Exception as e:
    note = "variant %s unavailable (%s); fell back to scalar_rgb" % (variant, str(e).splitlines()[0])
    variant = "scalar_rgb"
    mi.set_variant(variant)
dr.set_thread_count(cfg["threads"])
scene = mi.load_file(cfg["scene"], **cfg["defines"])
def render(seed):
    t0 = time.perf_counter()
    img = mi.render(scene, spp=cfg["spp"], seed=seed)
    dr.eval(img)
    if hasattr(dr, "sync_thread"):
        dr.sync_thread()
    try:
        img.numpy()  # forces evaluation on every variant
    except Exception:  # no numpy in that interpreter: dr.eval and sync_thread above waited
        pass
    return time.perf_counter() - t0
warmup = render(1000)
print(json.dumps({"ready": True, "variant": variant, "note": note, "version": mi.__version__,
                  "warmup_s": warmup}), flush=True)
for line in sys.stdin:
    seed = int(line)
    print(json.dumps({"seconds": render(seed)}), flush=True)
"""


def run_gdmlt(args, out_dir: Path, run: int) -> dict:
    stats_path = out_dir / f"stats_{run}.json"
    cmd = [args.gdmlt, "render", str(args.scene), "-D", f"max_depth={args.max_depth}",
           "-D", f"res={args.res}", "--spp", str(args.spp), "-t", str(args.threads),
           "--seed", str(run), "-q", "-o", str(out_dir / f"img_{run}.exr"),
           "--stats", str(stats_path)]
    subprocess.run(cmd, check=True)
    return json.loads(stats_path.read_text())


# Per integrator of --integrators: the --stats field holding its rate, the rate's unit, the
# phase it is measured over, and the phases outside it (reported beside it, not in it).
OTHER_RATES = {
    "pssmlt": {"field": "mutations_per_s", "unit": "mutations/s", "over": "chains_s",
               "excluded": ["bootstrap_s", "direct_s"]},
    "gdpt": {"field": "samples_per_s", "unit": "samples/s", "over": "sampling_s",
             "excluded": ["reconstruct_s"]},
    "gdmlt": {"field": "proposals_per_s", "unit": "proposals/s", "over": "chains_s",
              "excluded": ["bootstrap_s", "very_direct_s", "light_tracing_s", "reconstruct_s"]},
}


def run_other(args, integrator: str, out_dir: Path, run: int) -> dict:
    """One render by `integrator` with the path tracer's scene, resolution, max_depth, threads
    and seed of run `run`, and its work: spp samples per pixel (gdpt) or as many mutations per
    pixel (pssmlt, gdmlt). Returns the --stats JSON."""
    stats_path = out_dir / f"stats_{integrator}_{run}.json"
    cmd = [args.gdmlt, "render", str(args.scene), "--integrator", integrator,
           "-D", f"max_depth={args.max_depth}", "-D", f"res={args.res}",
           "--spp", str(args.spp), "-t", str(args.threads), "--seed", str(run), "-q",
           "-o", str(out_dir / f"img_{integrator}_{run}.exr"), "--stats", str(stats_path)]
    if integrator != "gdpt":
        cmd += ["--mpp", str(args.spp)]
    subprocess.run(cmd, check=True)
    return json.loads(stats_path.read_text())


def callgrind_inclusive(out_file: Path) -> dict[str, int]:
    """Inclusive Ir per function name (symbol without file and object). With debug info a
    function is listed once per source file that contributed inlined code; the entry of its own
    file carries the full inclusive cost, so the largest is kept (summing would double count)."""
    text = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100",
                           str(out_file)], check=True, capture_output=True, text=True).stdout
    costs: dict[str, int] = {}
    line_re = re.compile(r"^\s*([\d,]+)\s+(?:\([^)]*\)\s+)?(\S+?):(.*?)(?:\s+\[[^\]]*\])?\s*$")
    for line in text.splitlines():
        m = line_re.match(line)
        if not m:
            continue
        name = m.group(3)
        costs[name] = max(costs.get(name, 0), int(m.group(1).replace(",", "")))
    return costs


def embree_fraction_callgrind(args, out_dir: Path) -> dict:
    if not shutil.which("valgrind") or not shutil.which("callgrind_annotate"):
        return {"error": "valgrind/callgrind_annotate not found"}
    out_file = out_dir / "callgrind.out"
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out_file}", args.gdmlt,
           "render", str(args.scene), "-D", f"max_depth={args.max_depth}", "-D",
           f"res={args.profile_res}", "--spp", str(args.profile_spp), "-t", "1", "-q", "-o",
           str(out_dir / "callgrind.exr"), "--stats", str(out_dir / "callgrind_stats.json")]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    costs = callgrind_inclusive(out_file)
    render = max((c for n, c in costs.items()
                  if n.startswith("gdmlt::render_path(") and "lambda" not in n), default=0)
    embree = sum(c for n, c in costs.items() if re.match(r"rtc(Intersect|Occluded)\w*$", n))
    stats = json.loads((out_dir / "callgrind_stats.json").read_text())
    samples = stats["samples"]
    rays = stats["rays"]["total"]
    if render <= 0:
        return {"error": "gdmlt::render_path not found in the profile (stripped binary?)"}
    return {"method": "callgrind", "res": args.profile_res, "spp": args.profile_spp,
            "render_Ir": render, "embree_Ir": embree, "fraction": embree / render,
            "Ir_per_sample": render / samples, "Ir_per_ray": render / rays,
            "embree_Ir_per_ray": embree / rays, "rays_per_sample": rays / samples}


def embree_fraction_perf(args, out_dir: Path) -> dict:
    if not shutil.which("perf"):
        return {"error": "perf not found"}
    data = out_dir / "perf.data"
    cmd = ["perf", "record", "-q", "-e", "cpu-clock", "-F", "1999", "-o", str(data), args.gdmlt,
           "render", str(args.scene), "-D", f"max_depth={args.max_depth}", "-D",
           f"res={args.res}", "--spp", str(args.spp), "-t", str(args.threads), "-q", "-o",
           str(out_dir / "perf.exr")]
    if subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode:
        return {"error": "perf record failed (perf_event_paranoid?)"}
    report = subprocess.run(["perf", "report", "-i", str(data), "--sort", "dso", "--stdio",
                             "-F", "sample,dso", "--no-children"], capture_output=True,
                            text=True).stdout
    per_dso: dict[str, int] = {}
    for line in report.splitlines():
        m = re.match(r"^\s*(\d+)\s+(\S.*?)\s*$", line)
        if m:
            per_dso[m.group(2)] = per_dso.get(m.group(2), 0) + int(m.group(1))
    counted = {d: n for d, n in per_dso.items() if "ld-linux" not in d and "kernel" not in d}
    total = sum(counted.values())
    embree = sum(n for d, n in counted.items() if "embree" in d)
    if total == 0:
        return {"error": "no samples"}
    return {"method": "perf cpu-clock", "samples": total, "fraction": embree / total,
            "top": sorted(counted.items(), key=lambda kv: -kv[1])[:5]}


def find_libllvm() -> str | None:
    best = None
    for path in glob.glob("/usr/lib/*/libLLVM-*.so") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"):
        m = re.search(r"libLLVM-(\d+)\.so$", path) or re.search(r"llvm-(\d+)/", path)
        if m and int(m.group(1)) >= 16 and (best is None or int(m.group(1)) > best[0]):
            best = (int(m.group(1)), path)
    return best[1] if best else None


class MitsubaWorker:
    def __init__(self, args):
        env = dict(os.environ)
        if args.mitsuba_variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in env:
            lib = find_libllvm()
            if lib:
                env["DRJIT_LIBLLVM_PATH"] = lib
        self.libllvm = env.get("DRJIT_LIBLLVM_PATH")
        cfg = {"variant": args.mitsuba_variant, "threads": args.threads,
               "scene": str(args.scene), "spp": args.spp,
               "defines": {"max_depth": args.max_depth, "res": args.res}}
        self.proc = subprocess.Popen([args.mitsuba_python, "-c", MITSUBA_WORKER, json.dumps(cfg)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True, env=env,
                                     cwd=str(REPO))
        self.info = self._read()

    def _read(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            return {"error": "Mitsuba worker exited"}
        return json.loads(line)

    def render(self, seed: int) -> float:
        self.proc.stdin.write(f"{seed}\n")
        self.proc.stdin.flush()
        return self._read()["seconds"]

    def close(self):
        if self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=60)


def raw_embree(args) -> dict:
    """rays/s per kind (camera, bounce, shadow) of bench_embree at args.threads threads."""
    if not Path(args.bench_embree).exists():
        return {"error": f"{args.bench_embree} not found"}
    env = dict(os.environ, GDMLT_BENCH_SCENE=str(args.scene),
               GDMLT_BENCH_DEFINES=f"res={args.res},max_depth={args.max_depth}")
    out = subprocess.run([args.bench_embree, "--benchmark_format=json", "--benchmark_min_time=0.5",
                          # The renderer's kinds only (not `random`, which is for comparing
                          # ray rates with Mitsuba 3: bench/mitsuba_rays.py).
                          "--benchmark_filter=/(camera|camera_pixel|camera_pixel_coherent|bounce"
                          f"|shadow)/.*threads:{args.threads}$"],
                         capture_output=True, text=True, env=env)
    if out.returncode != 0:
        return {"error": out.stderr.strip()[-300:]}
    rates, packet_rates = {}, {}
    for b in json.loads(out.stdout)["benchmarks"]:
        form, kind = b["name"].split("/")[:2]
        (packet_rates if form == "BM_Embree_packet" else rates)[kind] = b["items_per_second"]
    kinds = {"camera", "bounce", "shadow"}
    camera_forms = {"camera_pixel", "camera_pixel_coherent"}
    if set(rates) != kinds or set(packet_rates) != kinds | camera_forms:
        return {"error": f"unexpected benchmarks {sorted(rates)} {sorted(packet_rates)}"}
    # The wavefront's camera packets: one pixel's samples, flagged coherent (docstring).
    camera_packets = {k: packet_rates.pop(k) for k in ["camera", *sorted(camera_forms)]}
    packet_rates = {"camera": camera_packets["camera_pixel_coherent"], **packet_rates}
    return {"rays_per_s": rates, "packet_rays_per_s": packet_rates,
            "camera_packet_rays_per_s": camera_packets}


def summary(values: list[float]) -> str:
    return (f"median {statistics.median(values):.4g}  (min {min(values):.4g}, "
            f"max {max(values):.4g}, n={len(values)})")


def other_rates(args, others: dict[str, list[dict]], ours_sps: list[float],
                all_stats: list[dict]) -> dict:
    """Prints, per integrator of --integrators, its rate (median over runs) and its rate over the
    path tracer's samples/s of the same run (per run and median), and the median times of the
    phases its rate excludes; returns all of these for the JSON."""
    out = {}
    path_render_s = [s["render_s"] for s in all_stats]
    for name, runs in others.items():
        spec = OTHER_RATES[name]
        rates = [r[spec["field"]] for r in runs]
        ratios = [a / b for a, b in zip(rates, ours_sps)]
        seconds = {k: [r.get(k, 0.0) for r in runs]
                   for k in [spec["over"], *spec["excluded"], "render_s"]}
        print(f"{name} {spec['unit']}: {summary(rates)}; per run / path tracer samples/s: "
              f"{summary(ratios)}")
        excluded = [f"{k[:-2]} {statistics.median(seconds[k]):.3g} s" for k in spec["excluded"]
                    if any(seconds[k])]
        print(f"  {name} time (medians): {spec['over'][:-2]} "
              f"{statistics.median(seconds[spec['over']]):.3g} s (the rate's); excluded: "
              f"{', '.join(excluded) or 'nothing'}; render_s "
              f"{statistics.median(seconds['render_s']):.3g} s (path tracer's "
              f"{statistics.median(path_render_s):.3g} s)")
        out[name] = {"field": spec["field"], "unit": spec["unit"], "over": spec["over"],
                     "excluded": spec["excluded"], "work_per_pixel": args.spp,
                     "work": [r["mutations"] if "mutations" in r else r["samples"] for r in runs],
                     "rate": rates, "rate_median": statistics.median(rates),
                     "ratio_to_path_samples_per_s": ratios,
                     "ratio_median": statistics.median(ratios), "seconds": seconds}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gdmlt", default=str(REPO / "build/release/gdmlt"))
    ap.add_argument("--scene", type=Path, default=REPO / "scenes/cbox.xml")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--embree-fraction", choices=["callgrind", "perf", "both", "none"],
                    default="callgrind")
    ap.add_argument("--profile-res", type=int, default=64)
    ap.add_argument("--profile-spp", type=int, default=4)
    ap.add_argument("--mitsuba", choices=["auto", "off"], default="auto")
    ap.add_argument("--mitsuba-python", default=sys.executable,
                    help="interpreter that can import mitsuba (e.g. a venv's python)")
    ap.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    ap.add_argument("--bench-embree", default=None,
                    help="bench_embree executable (default: bench/ beside --gdmlt)")
    ap.add_argument("--integrators", nargs="*", choices=[*OTHER_RATES, "none"],
                    default=list(OTHER_RATES),
                    help="also render with these in every run and report their rates against "
                         "the path tracer's samples/s (none or nothing: skip)")
    ap.add_argument("--json", type=Path, help="also write all numbers here")
    args = ap.parse_args()
    args.integrators = [i for i in dict.fromkeys(args.integrators) if i != "none"]
    args.scene = args.scene.resolve()
    if args.bench_embree is None:
        args.bench_embree = str(Path(args.gdmlt).resolve().parent / "bench" / "bench_embree")
    if not Path(args.gdmlt).exists():
        print(f"gdmlt binary not found: {args.gdmlt} (build it first)", file=sys.stderr)
        return 2

    print(f"scene {args.scene.name}: {args.res}x{args.res}, {args.spp} spp, max_depth "
          f"{args.max_depth}, {args.threads} threads, {args.runs} runs")
    result: dict = {"settings": {k: str(v) for k, v in vars(args).items()}}

    mitsuba = None
    if args.mitsuba == "auto":
        mitsuba = MitsubaWorker(args)
        if "error" in mitsuba.info:
            print(f"Mitsuba 3: not run ({mitsuba.info['error']}; try --mitsuba-python)")
            result["mitsuba"] = mitsuba.info
            mitsuba.close()
            mitsuba = None
        else:
            note = f"; {mitsuba.info['note']}" if mitsuba.info["note"] else ""
            print(f"Mitsuba {mitsuba.info['version']} variant {mitsuba.info['variant']} "
                  f"(LLVM: {mitsuba.libllvm or 'n/a'}), warm-up {mitsuba.info['warmup_s']:.2f} s"
                  f"{note}")

    with tempfile.TemporaryDirectory(prefix="gdmlt_throughput_") as tmp:
        out_dir = Path(tmp)
        ours_sps, ours_rps, theirs_sps, all_stats = [], [], [], []
        others: dict[str, list[dict]] = {name: [] for name in args.integrators}
        for run in range(args.runs):
            stats = run_gdmlt(args, out_dir, run)
            all_stats.append(stats)
            ours_sps.append(stats["samples_per_s"])
            ours_rps.append(stats["rays"]["per_s"])
            line = (f"  run {run}: gdmlt {stats['samples_per_s'] / 1e6:.3f} M samples/s, "
                    f"{stats['rays']['per_s'] / 1e6:.2f} M rays/s")
            if mitsuba:
                seconds = mitsuba.render(run)
                theirs_sps.append(args.res * args.res * args.spp / seconds)
                line += f"; Mitsuba {theirs_sps[-1] / 1e6:.3f} M samples/s"
            print(line, flush=True)
            if args.integrators:
                parts = []
                for name in args.integrators:
                    other = run_other(args, name, out_dir, run)
                    others[name].append(other)
                    spec = OTHER_RATES[name]
                    rate = other[spec["field"]]
                    parts.append(f"{name} {rate / 1e6:.3f} M {spec['unit']} "
                                 f"({rate / stats['samples_per_s']:.2f}x path tracer)")
                print(f"  run {run}: " + ", ".join(parts), flush=True)
        rays_per_sample = stats["rays"]["total"] / max(stats["samples"], 1)
        print(f"gdmlt samples/s: {summary(ours_sps)}")
        print(f"gdmlt rays/s:    {summary(ours_rps)}  ({rays_per_sample:.2f} rays per sample)")
        result["gdmlt"] = {"samples_per_s": ours_sps, "rays_per_s": ours_rps,
                           "rays_per_sample": rays_per_sample,
                           "render_s": [s["render_s"] for s in all_stats]}
        if args.integrators:
            result["mlt_rates"] = other_rates(args, others, ours_sps, all_stats)
        if mitsuba:
            mitsuba.close()
            ratio = statistics.median(ours_sps) / statistics.median(theirs_sps)
            per_run = [a / b for a, b in zip(ours_sps, theirs_sps)]
            print(f"Mitsuba samples/s: {summary(theirs_sps)}")
            print(f"ratio gdmlt / Mitsuba: {ratio:.2f} (of medians); per interleaved pair "
                  f"{summary(per_run)}")
            result["mitsuba"] = dict(mitsuba.info, samples_per_s=theirs_sps, ratio=ratio,
                                     ratio_per_run=per_run)

        raw = raw_embree(args)
        result["raw_embree"] = raw
        if "error" in raw:
            print(f"raw Embree: not measured ({raw['error']})")
        else:
            def shares_at(rates: dict) -> list[float]:
                return [sum(s["rays"][k] / rates[k] for k in rates) / s["render_s"]
                        for s in all_stats]

            rates, packet_rates = raw["rays_per_s"], raw["packet_rays_per_s"]
            shares, packet_shares = shares_at(rates), shares_at(packet_rates)
            raw["path_share_of_raw"] = shares
            raw["path_share_of_raw_packets"] = packet_shares
            for label, r in (("single rays", rates), ("packets of 16", packet_rates)):
                print(f"raw Embree (bench_embree, {args.threads} threads, {label}): " +
                      ", ".join(f"{k} {v / 1e6:.2f}" for k, v in r.items()) + " M rays/s")
            print("raw Embree camera packets (the packet rate above is the coherent one): " +
                  ", ".join(f"{k} {v / 1e6:.2f}" for k, v in raw["camera_packet_rays_per_s"].items())
                  + " M rays/s")
            print(f"path tracer at {statistics.median(shares):.1%} of raw Embree (its rays at raw "
                  f"Embree's rates / its render time; per run {summary(shares)})")
            print(f"path tracer at {statistics.median(packet_shares):.1%} of raw Embree's packet "
                  f"rates (per run {summary(packet_shares)})")

        methods = {"both": ["callgrind", "perf"], "none": []}.get(args.embree_fraction,
                                                                   [args.embree_fraction])
        for method in methods:
            t0 = time.perf_counter()
            f = (embree_fraction_callgrind if method == "callgrind" else embree_fraction_perf)(
                args, out_dir)
            result[f"embree_{method}"] = f
            if "error" in f:
                print(f"Embree fraction ({method}): not measured: {f['error']}")
            elif method == "callgrind":
                print(f"Embree fraction (callgrind Ir, {f['res']}x{f['res']}, {f['spp']} spp, "
                      f"1 thread): {f['fraction']:.1%}; {f['Ir_per_sample']:.0f} Ir/sample, "
                      f"{f['embree_Ir_per_ray']:.0f} Embree Ir/ray "
                      f"[{time.perf_counter() - t0:.0f} s]")
            else:
                print(f"Embree fraction (perf cpu-clock, full render): {f['fraction']:.1%} "
                      f"of {f['samples']} samples")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
