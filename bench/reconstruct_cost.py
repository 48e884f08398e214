#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""What accuracy costs in time: L2, L1 and CV reconstruction against iteration count and
tolerance, at 512x512 and 1280x720.

Runs the Google Benchmark binary bench_reconstruct (built by bench/CMakeLists.txt), takes the
median wall time of repeated runs (this machine is shared and noisy), prints a table and saves
bench/out/reconstruct_cost.png (RMSE against time, one curve per method and size).

With --cli PATH (the gdmlt executable, or any driver exposing the `reconstruct` subcommand) it
also writes a synthetic raw.exr with layers primal/dx/dy through OpenImageIO and times the
command end to end (file I/O included) for each method.

With --scenes (names, or none for every scene with a reference) it measures the methods on
real renders instead of the micro-benchmarks (add --micro for both): per scene one GDPT render
(`gdmlt render --integrator gdpt --spp N`, or --time), then `gdmlt reconstruct` of that raw
EXR with each of --methods, compared with --references/NAME.exr. Per scene and method it
prints relMSE (bench/metrics.py), the mean ratio (image mean / reference mean: lost or added
energy) and the low-pass relMSE (8x8 box-downsampled image against the downsampled
reference: coarse-scale error once pixel noise has averaged out), and writes
bench/out/reconstruct_scenes.json. Method "primal" is the raw primal + very_direct (no
reconstruction); "l1" is pure L1 (--huber 0) and "huber" L1 with Huber rows where the variance
layers give the noise (--huber 1.345, the render default); "cv-count" is cv on a copy of the EXR without the variance layers, i.e. cv
with Var(primal) = 1 / sample_count and exact differences. Scenes are looked up in
--scene-dir (default ../shared/scenes beside the repository), then in scenes/.

  /usr/bin/python3 bench/reconstruct_cost.py   (Debian python: numpy, matplotlib, OpenImageIO)
  python3 bench/reconstruct_cost.py --bench build/release/bench/bench_reconstruct \
      [--repetitions 5] [--filter BM_L2] [--cli build/release/gdmlt] [--image render.exr]
  python3 bench/reconstruct_cost.py --scenes cbox caustic_glass_light [--spp 64 | --time 16] \
      [--methods primal l1 l2 cv cv-count] [--references DIR] [--threads 2] [--seed 0]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# metrics.py is imported where it is used: it needs OpenImageIO, which the synthetic sweep does
# not.
sys.path.insert(0, HERE)
OUT = os.path.join(HERE, "out")
ROOT = os.path.dirname(HERE)
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
VARIANCE_LAYERS = ("primal_variance", "dx_variance", "dy_variance")


def run_benchmark(binary, repetitions, flt, image):
    env = dict(os.environ)
    if image:
        env["GDMLT_BENCH_IMAGE"] = image
    cmd = [binary, "--benchmark_format=json", f"--benchmark_repetitions={repetitions}",
           f"--benchmark_filter={flt}"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
    runs = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("run_type") != "iteration":
            continue
        name = b["run_name"]
        runs.setdefault(name, []).append(b)
    rows = []
    for name, bs in runs.items():
        method, w, h, a, b = name.replace("/real_time", "").split("/")[:5]
        ms = statistics.median(x["real_time"] for x in bs)  # Unit is milliseconds
        rows.append({"method": method[3:], "size": f"{w}x{h}", "a": int(a), "b": int(b),
                     "ms": ms, "rmse": bs[0]["rmse"], "primal_rmse": bs[0]["primal_rmse"],
                     "iterations": int(bs[0]["iterations"]),
                     "cg": int(bs[0]["cg_iterations"]), "residual": bs[0]["residual"],
                     "setup_ms": 1e3 * statistics.median(x["setup_s"] for x in bs)})
    return rows


def describe(r):
    if r["method"] == "L2":
        return f"tol 1e-{r['a']}, max {r['b']} CG"
    if r["method"] == "L1":
        return f"{r['a']} IRLS x <= {r['b']} CG"
    return f"{r['a']} its, {'weighted' if r['b'] else 'uniform'}"


def print_table(rows):
    print(f"{'method':6} {'size':9} {'setting':24} {'time ms':>9} {'setup ms':>9} "
          f"{'CG its':>7} {'rel.res':>9} {'RMSE':>9} {'primal':>9}")
    for r in rows:
        print(f"{r['method']:6} {r['size']:9} {describe(r):24} {r['ms']:9.1f} "
              f"{r['setup_ms']:9.1f} {r['cg']:7d} {r['residual']:9.2e} {r['rmse']:9.5f} "
              f"{r['primal_rmse']:9.5f}")


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 5))
    groups = {}
    for r in rows:
        groups.setdefault((r["method"], r["size"]), []).append(r)
    for (method, size), rs in sorted(groups.items()):
        rs = sorted(rs, key=lambda r: r["ms"])
        ax.plot([r["ms"] / 1e3 for r in rs], [r["rmse"] for r in rs], marker="o",
                label=f"{method} {size}")
    for target, label in ((0.3, "L2 target 0.3 s"), (2.0, "L1 target 2 s")):
        ax.axvline(target, color="grey", linestyle=":", linewidth=1)
        ax.text(target, ax.get_ylim()[1], label, rotation=90, va="top", fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("wall time per reconstruction [s] (median)")
    ax.set_ylabel("RMSE against the clean image")
    ax.set_title("gdmlt reconstruction: what accuracy costs in time")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def cli_timing(cli, repetitions):
    """End-to-end `reconstruct` timing on a synthetic 1280x720 raw.exr."""
    import OpenImageIO as oiio
    import metrics
    w, h = 1280, 720
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    clean = np.stack([0.5 + 0.4 * np.sin(xx / 90.0), 0.3 + 0.3 * (yy / h),
                      np.where(xx > w / 3, 0.8, 0.2)], axis=-1).astype(np.float32)
    rng = np.random.default_rng(1)
    primal = clean + rng.normal(0, 0.05, clean.shape).astype(np.float32)
    dx, dy = metrics.forward_differences(clean)
    dx += rng.normal(0, 0.01, dx.shape).astype(np.float32)
    dy += rng.normal(0, 0.01, dy.shape).astype(np.float32)
    data = np.concatenate([primal, dx, dy], axis=-1)
    with tempfile.TemporaryDirectory() as tmp:
        raw = os.path.join(tmp, "raw.exr")
        spec = oiio.ImageSpec(w, h, 9, "float")
        spec.channelnames = tuple(f"{l}.{c}" for l in ("primal", "dx", "dy") for c in "RGB")
        out = oiio.ImageOutput.create(raw)
        out.open(raw, spec)
        out.write_image(data)
        out.close()
        print(f"\nCLI end to end ({cli} reconstruct, 1280x720, file I/O included):")
        for method in ("l2", "l1", "cv"):
            times = []
            for _ in range(repetitions):
                t0 = time.perf_counter()
                subprocess.run([cli, "reconstruct", raw, "--method", method, "-q", "-o",
                                os.path.join(tmp, f"final_{method}.exr")], check=True)
                times.append(time.perf_counter() - t0)
            final = oiio.ImageBuf(os.path.join(tmp, f"final_{method}.exr")).get_pixels(
                oiio.FLOAT)[:, :, :3]
            err = float(np.sqrt(np.mean((final - clean) ** 2)))
            print(f"  {method}: {statistics.median(times):.3f} s median of {repetitions}, "
                  f"RMSE {err:.5f} (primal {float(np.sqrt(np.mean((primal - clean) ** 2))):.5f})")


def resolve_scene(name, scene_dir):
    """A scene name (cbox) or a path to an .xml file -> path of the scene file."""
    if name.endswith(".xml") and os.path.isfile(name):
        return os.path.abspath(name)
    for directory in (scene_dir, os.path.join(ROOT, "scenes")):
        path = os.path.join(directory, name + ".xml")
        if os.path.isfile(path):
            return path
    sys.exit(f"scene {name!r} not found in {scene_dir} or {os.path.join(ROOT, 'scenes')}")


def without_variance_layers(raw, path):
    """Copy of a raw EXR without the variance layers (header kept): what reconstruction sees
    of a render that only had sample counts."""
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(raw)
    keep = tuple(n for n in buf.spec().channelnames if n.split(".")[0] not in VARIANCE_LAYERS)
    stripped = oiio.ImageBufAlgo.channels(buf, keep)
    if not stripped.write(path):
        raise RuntimeError(f"{path}: {stripped.geterror()}")
    return path


def scene_comparison(args, cli):
    """Each reconstruction method on a GDPT render of each scene against its reference."""
    import metrics
    names = args.scenes or sorted(os.path.splitext(f)[0] for f in os.listdir(args.references)
                                  if f.endswith(".exr"))
    budget = ["--time", str(args.time)] if args.time else ["--spp", str(args.spp)]
    threads = ["-t", str(args.threads)] if args.threads else []
    rows = []
    print(f"{'scene':22} {'method':9} {'relMSE':>10} {'mean':>7} {'low-pass':>10} {'time s':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            scene = resolve_scene(name, args.scene_dir)
            stem = os.path.splitext(os.path.basename(scene))[0]
            reference = metrics.read_rgb(os.path.join(args.references, stem + ".exr"))
            raw = os.path.join(tmp, stem + "_raw.exr")
            subprocess.run([cli, "render", scene, "--integrator", "gdpt", "--seed",
                            str(args.seed), "-q", "-o", raw] + budget + threads, check=True)
            for method in args.methods:
                seconds = 0.0
                if method == "primal":
                    image = metrics.read_rgb(raw, "primal") + metrics.read_rgb(raw, "very_direct")
                else:
                    source = raw
                    if method == "cv-count":
                        source = without_variance_layers(raw, os.path.join(tmp, stem + "_nv.exr"))
                    final = os.path.join(tmp, f"{stem}_{method}.exr")
                    t0 = time.perf_counter()
                    # l1 is pure L1 and huber L1 with Huber rows (--huber), whatever the render's
                    # default; the others take the render's settings.
                    huber = {"l1": ["--huber", "0"], "huber": ["--huber", "1.345"]}.get(method, [])
                    solver = "l1" if method == "huber" else method.split("-")[0]
                    subprocess.run([cli, "reconstruct", source, "--method", solver, "-q", "-o",
                                    final] + huber + threads, check=True)
                    seconds = time.perf_counter() - t0
                    image = metrics.read_rgb(final)
                if image.shape != reference.shape:
                    sys.exit(f"{stem}: render {image.shape} and reference {reference.shape} differ")
                row = {"scene": stem, "method": method,
                       "rel_mse": metrics.rel_mse(image, reference),
                       "mean_ratio": float(image.mean() / reference.mean()),
                       "low_pass_rel_mse": metrics.low_pass_rel_mse(image, reference),
                       "reconstruct_s": seconds}
                rows.append(row)
                print(f"{stem:22} {method:9} {row['rel_mse']:10.5f} {row['mean_ratio']:7.3f} "
                      f"{row['low_pass_rel_mse']:10.5f} {seconds:7.2f}", flush=True)
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "reconstruct_scenes.json")
    with open(path, "w") as f:
        json.dump({"budget": budget, "seed": args.seed, "threads": args.threads, "rows": rows}, f,
                  indent=1)
    print(f"\nresults: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", default=os.path.join(HERE, "..", "build", "release", "bench",
                                                     "bench_reconstruct"))
    ap.add_argument("--repetitions", type=int, default=5)
    ap.add_argument("--filter", default=".")
    ap.add_argument("--image", help="rendered EXR/PNG to use as the clean image")
    ap.add_argument("--cli", help="gdmlt executable: also time `reconstruct` end to end "
                    "(with --scenes: the renderer, default build/release/gdmlt)")
    ap.add_argument("--scenes", nargs="*", help="compare the methods on GDPT renders of these "
                    "scenes (no names: every scene with a reference) instead of the "
                    "micro-benchmarks")
    ap.add_argument("--micro", action="store_true", help="with --scenes: also the micro-benchmarks")
    ap.add_argument("--methods", nargs="+",
                    default=["primal", "l1", "huber", "l2", "cv", "cv-count"],
                    choices=["primal", "l1", "huber", "l2", "cv", "cv-count"])
    ap.add_argument("--spp", type=int, default=64, help="GDPT samples per pixel (--scenes)")
    ap.add_argument("--time", type=float, help="GDPT time budget in seconds instead of --spp")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0, help="0: gdmlt's default (all cores)")
    ap.add_argument("--scene-dir", default=os.path.join(SHARED, "scenes"))
    ap.add_argument("--references", default=os.path.join(SHARED, "references"))
    args = ap.parse_args()
    if args.scenes is not None:
        cli = args.cli or os.path.join(ROOT, "build", "release", "gdmlt")
        if not os.path.exists(cli):
            sys.exit(f"gdmlt executable not found: {cli} (cmake --build build/release)")
        scene_comparison(args, cli)
        if not args.micro:
            return
    if not os.path.exists(args.bench):
        sys.exit(f"benchmark binary not found: {args.bench} (cmake --build build/release)")
    rows = run_benchmark(args.bench, args.repetitions, args.filter, args.image)
    print_table(rows)
    os.makedirs(OUT, exist_ok=True)
    png = os.path.join(OUT, "reconstruct_cost.png")
    plot(rows, png)
    print(f"\nplot: {png}")
    if args.cli:
        cli_timing(args.cli, max(1, min(args.repetitions, 3)))


if __name__ == "__main__":
    main()
