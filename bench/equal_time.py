#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Equal-time comparison of integrators: relative MSE against the Mitsuba 3 references at
several time budgets, printed as a Markdown table and plotted as error-vs-time curves.

    bench/equal_time.py --scenes cbox_glass_sphere caustic_glass_light \\
                        --integrators path pssmlt --times 5 10 20

An integrator may carry options as a variant, `NAME:KEY=VALUE[,KEY=VALUE...]`, which adds
`--KEY VALUE` to that run only, e.g. `--integrators gdpt gdpt:shift=reconnect` compares GDPT with
and without the manifold shift in one run.

Every run is `gdmlt render SCENE --integrator I --time T -t THREADS` on the scene files in
scenes/, compared with ../shared/references/SCENE.exr (metric: bench/metrics.py). Each
configuration runs --repeats times with different seeds; the table gives the median relMSE,
the plot every run. The machine is shared: compare integrators within one run of this script.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import metrics  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def parse_variant(spec):
    """'gdpt:shift=reconnect,foo=1' -> ('gdpt', ['--shift', 'reconnect', '--foo', '1'])."""
    name, _, options = spec.partition(":")
    args = []
    for option in filter(None, options.split(",")):
        key, sep, value = option.partition("=")
        if not sep:
            raise SystemExit(f"integrator variant option without a value: {option!r} in {spec!r}")
        args += [f"--{key}", value]
    return name, args


def render(binary, scene, integrator, seconds, threads, seed, out_dir, extra):
    integrator, variant_args = parse_variant(integrator)
    tag = "_".join(a.lstrip("-") for a in variant_args)
    stem = f"{os.path.basename(scene)[:-4]}_{integrator}{'_' + tag if tag else ''}_{seconds:g}s_seed{seed}"
    exr = os.path.join(out_dir, stem + ".exr")
    stats = os.path.join(out_dir, stem + ".json")
    cmd = [binary, "render", scene, "--integrator", integrator, "--time", str(seconds), "-t", str(threads),
           "--seed", str(seed), "-o", exr, "--stats", stats, "-q"] + variant_args + extra
    subprocess.run(cmd, check=True)
    with open(stats) as f:
        return exr, json.load(f)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    parser.add_argument("--scenes", nargs="+", default=["cbox_glass_sphere", "caustic_glass_light"])
    parser.add_argument("--integrators", nargs="+", default=["path", "pssmlt"])
    parser.add_argument("--times", nargs="+", type=float, default=[5, 10, 20])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--references", default=os.path.join(ROOT, "..", "shared", "references"))
    parser.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "equal_time"))
    parser.add_argument("--extra", default="", help="extra gdmlt arguments, e.g. '-D res=128'")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    results = {}  # (scene, integrator, time) -> list of relMSE
    for scene in args.scenes:
        reference = metrics.read_rgb(os.path.join(args.references, scene + ".exr"))
        for seconds in args.times:
            for integrator in args.integrators:
                for seed in range(args.repeats):
                    exr, stats = render(args.binary, os.path.join(ROOT, "scenes", scene + ".xml"), integrator,
                                        seconds, args.threads, seed, args.out, args.extra.split())
                    error = metrics.rel_mse(metrics.read_rgb(exr), reference)
                    results.setdefault((scene, integrator, seconds), []).append(error)
                    print(f"{scene:22s} {integrator:20s} {seconds:6g} s  relMSE {error:.5f}  "
                          f"(wall {stats.get('render_s', 0):.1f} s)", flush=True)

    print()
    header = "| scene | time (s) | " + " | ".join(f"{i} relMSE" for i in args.integrators)
    if len(args.integrators) > 1:
        header += " | " + " | ".join(f"{args.integrators[0]}/{i}" for i in args.integrators[1:])
    print(header + " |")
    print("|" + "---|" * (header.count("|") - 1))
    for scene in args.scenes:
        for seconds in args.times:
            medians = [statistics.median(results[(scene, i, seconds)]) for i in args.integrators]
            row = f"| {scene} | {seconds:g} | " + " | ".join(f"{m:.4f}" for m in medians)
            if len(medians) > 1:
                row += " | " + " | ".join(f"{medians[0] / m:.2f}x" if m > 0 else "-" for m in medians[1:])
            print(row + " |")

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, axes = plt.subplots(1, len(args.scenes), figsize=(5 * len(args.scenes), 4), squeeze=False)
    for ax, scene in zip(axes[0], args.scenes):
        for integrator in args.integrators:
            xs, ys = [], []
            for seconds in args.times:
                for e in results[(scene, integrator, seconds)]:
                    xs.append(seconds)
                    ys.append(e)
            ax.loglog(xs, ys, "o-", label=integrator)
        ax.set_title(scene)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("relative MSE")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    path = os.path.join(args.out, "equal_time.png")
    fig.savefig(path, dpi=100)
    print(f"\nplot: {path}")


if __name__ == "__main__":
    main()
