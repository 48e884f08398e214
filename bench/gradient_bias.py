#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Are GDPT's differences unbiased over the whole image? A map of z-scores per image block.

For each scene it renders, with the same binary, resolution and thread count:
  * GDPT for --gdpt-time seconds: the difference layers dx, dy (A) and their variances
    dx_variance, dy_variance (the variance of each edge's mean difference);
  * the path tracer twice (seeds 100 and 101) for --path-time seconds each: P and Q.

Per block of --block x --block pixels and per direction (dx, dy) it compares the sum of the
GDPT differences with the sum of the path tracer's finite differences of P, each edge signed
by the sign of Q's finite difference there:

    z = sum_e s_e (A_e - dP_e) / sqrt(sum_e (Var A_e + Var dP_e)),   s_e = sign(dQ_e),
    Var dP_e estimated per edge as (dP_e - dQ_e)^2 / 2.

The signs come from Q, which is independent of A and P, so that s_e picks out edges where the
image changes without correlating with either estimate's noise (signing by P's own
differences would bias z negative wherever the noise is larger than the gradient). Without
bias z is about standard normal per block; a shift whose Jacobian or MIS weights are wrong
shows as blocks of large |z| of one sign. Edges touching a pixel with very direct light (an
emitter seen directly: never shifted, so not in the differences) are left out. The variance
layers average the RGB channels' variances, which bounds the variance of the RGB mean that is
compared here, so z errs small.

Found this way: the joint four-way MIS weights the estimator once had (gradient-mts's) gave
z = +39 on materials_envmap's metal sphere at 64x64; each technique's own weights, 2.9 at most.

    bench/gradient_bias.py --scenes materials_envmap cbox_glass_sphere --res 64
Prints the map and a summary line per scene; writes gradient_bias.json to --out; exits 1 when
a block's |z| exceeds --z-max (5 by default: a false alarm with probability 6e-7 per block and
direction for a normal z), 0 otherwise.
"""
import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import metrics  # noqa: E402
from equal_time import resolve_scene, scene_name  # noqa: E402


def render(args, scene, integrator, seconds, spp, seed, out):
    """One render; a fixed spp (deterministic at any thread count) when given, else a time."""
    budget = ["--spp", str(spp)] if spp else ["--time", str(seconds)]
    command = [args.binary, "render", scene, "--integrator", integrator, *budget, "--seed", str(seed), "-t", str(args.threads), "-D", f"res={args.res}", "-q", "-o", out]
    subprocess.run(command, check=True)


def rgb_mean(path, layer=""):
    return metrics.read_rgb(path, layer).mean(axis=2)


def edge_masks(very_direct):
    """Edges both of whose pixels have no very direct light (and that exist)."""
    clear = ~very_direct
    ok_x = clear.copy()
    ok_x[:, :-1] &= clear[:, 1:]
    ok_x[:, -1] = False
    ok_y = clear.copy()
    ok_y[:-1, :] &= clear[1:, :]
    ok_y[-1, :] = False
    return ok_x, ok_y


def block_z_scores(gdpt_exr, path_p, path_q, block):
    """List of rows of (z_dx, z_dy) per block (None where a block has no edge with variance)."""
    a = (rgb_mean(gdpt_exr, "dx"), rgb_mean(gdpt_exr, "dy"))
    var_a = (metrics.read_luminance(gdpt_exr, "dx_variance"),
             metrics.read_luminance(gdpt_exr, "dy_variance"))
    very_direct = rgb_mean(gdpt_exr, "very_direct") > 0.0
    masks = edge_masks(very_direct)
    p = metrics.forward_differences(rgb_mean(path_p))
    q = metrics.forward_differences(rgb_mean(path_q))
    height, width = very_direct.shape
    rows = []
    for y in range(0, height, block):
        row = []
        for x in range(0, width, block):
            cell = (slice(y, y + block), slice(x, x + block))
            pair = []
            for k in range(2):
                m = masks[k][cell]
                ak, pk, qk = a[k][cell][m], p[k][cell][m], q[k][cell][m]
                variance = (var_a[k][cell][m] + 0.5 * (pk - qk) ** 2).sum()
                if not (variance > 0.0) or not math.isfinite(variance):
                    pair.append(None)
                    continue
                pair.append(float((np.sign(qk) * (ak - pk)).sum() / math.sqrt(variance)))
            row.append(pair)
        rows.append(row)
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    parser.add_argument("--scenes", nargs="+", default=["materials_envmap"])
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--gdpt-time", type=float, default=30.0)
    parser.add_argument("--path-time", type=float, default=20.0, help="per path-traced image (two)")
    parser.add_argument("--gdpt-spp", type=int, help="samples per pixel instead of --gdpt-time")
    parser.add_argument("--path-spp", type=int, help="samples per pixel instead of --path-time")
    parser.add_argument("--block", type=int, default=16)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--z-max", type=float, default=5.0)
    parser.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "gradient_bias"))
    args = parser.parse_args()
    if not os.path.isfile(args.binary):
        raise SystemExit(f"gdmlt binary not found: {args.binary} (build it first)")
    os.makedirs(args.out, exist_ok=True)

    report = {"res": args.res, "block": args.block, "gdpt_time_s": args.gdpt_time,
              "path_time_s": args.path_time, "gdpt_spp": args.gdpt_spp, "path_spp": args.path_spp,
              "z_max": args.z_max, "scenes": {}}
    failed = False
    for name in args.scenes:
        scene = resolve_scene(name)
        stem = scene_name(scene)
        gdpt_exr = os.path.join(args.out, f"{stem}_gdpt.exr")
        path_exrs = [os.path.join(args.out, f"{stem}_path{h}.exr") for h in range(2)]
        render(args, scene, "gdpt", args.gdpt_time, args.gdpt_spp, 7, gdpt_exr)
        for h, out in enumerate(path_exrs):
            render(args, scene, "path", args.path_time, args.path_spp, 100 + h, out)
        rows = block_z_scores(gdpt_exr, path_exrs[0], path_exrs[1], args.block)
        values = [z for row in rows for pair in row for z in pair if z is not None]
        summary = {"blocks": len(values), "mean_z": float(np.mean(values)), "sd_z": float(np.std(values)),
                   "max_abs_z": float(np.max(np.abs(values))),
                   "over_4": sum(abs(z) > 4.0 for z in values), "map": rows}
        report["scenes"][stem] = summary
        print(f"{stem} ({args.res}x{args.res}, blocks of {args.block}): z of dx / dy per block")
        for row in rows:
            print("  " + "  ".join("/".join("  .  " if z is None else f"{z:+5.1f}" for z in pair) for pair in row))
        verdict = "ok" if summary["max_abs_z"] <= args.z_max else f"BIASED (|z| > {args.z_max:g})"
        print(f"{stem}: z mean {summary['mean_z']:+.2f} sd {summary['sd_z']:.2f} max |z| "
              f"{summary['max_abs_z']:.1f} over {summary['blocks']} block-directions, "
              f"{summary['over_4']} beyond 4: {verdict}")
        failed = failed or summary["max_abs_z"] > args.z_max
    with open(os.path.join(args.out, "gradient_bias.json"), "w") as f:
        json.dump(report, f, indent=1)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
