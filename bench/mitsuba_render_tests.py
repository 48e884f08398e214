#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Mitsuba 3's own render tests, run against gdmlt: each scene of mitsuba-data's tests/scenes
that has a reference image is rendered as written and compared with Mitsuba's reference by
Mitsuba's statistical test.

    bench/mitsuba_render_tests.py DIR [--threads 2] [--out out/mitsuba_render_tests]
                                      [--binary build/release/gdmlt] [--budget 2e6] [--seed 0]

DIR is a checkout of mitsuba-renderer/mitsuba-data. The test is the one in Mitsuba 3's
src/render/tests/test_renders.py, done the same way: a scene `NAME_INTEGRATOR.xml` is rendered
with the integrator its name ends with (`-D integrator=...`, which the scenes' <default>
reads) at spp = 2e6 / pixels (the reference's resolution), seed 0; the image, the reference
refs/NAME_ref_rgb.exr and its per-sample variance refs/NAME_ref_rgb_var.exr are turned into
CIE XYZ with the linear sRGB matrix (Mitsuba converts the variance image with the same matrix);
each pixel channel gets a two-sided z-test, |mean - reference| sqrt(spp / max(variance,
1e-4)), against a Sidak-corrected level 1 - 0.99^(1 / pixels); the scene passes when at least
99.75% of the pixel channels do. The table adds the ratio of the image means (RGB, ours over the
reference) and the relMSE against the reference (bench/metrics.py), and the smallest p-value.
Scenes gdmlt declines (exit 2, out of scope) are listed as such.

Writes mitsuba_render_tests.json and .md to --out and prints the table. Exit status 0: a
benchmark, not a test.
"""
import argparse
import glob
import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

from metrics import rel_mse  # noqa: E402

# Linear sRGB (Rec. 709 primaries, D65) to CIE XYZ, as Mitsuba 3's srgb_to_xyz.
SRGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423],
                        [0.212671, 0.715160, 0.072169],
                        [0.019334, 0.119193, 0.950227]])
OUT_OF_SCOPE = re.compile(r"is not supported: ([^\n]*)")


def read_rgb(path):
    buf = oiio.ImageBuf(path)
    pixels = buf.get_pixels(oiio.FLOAT)
    if pixels is None or buf.has_error:
        raise RuntimeError(f"cannot read {path}: {buf.geterror()}")
    names = list(buf.spec().channelnames)
    if all(c in names for c in "RGB"):
        return pixels[..., [names.index("R"), names.index("G"), names.index("B")]]
    return pixels[..., :3]


def to_xyz(rgb):
    return rgb @ SRGB_TO_XYZ.T


def z_test_p_values(mean, spp, reference, reference_variance):
    """Mitsuba's z_test: two-sided p-values of |mean - reference| per pixel channel."""
    variance = np.maximum(reference_variance, 1e-4)
    z = np.abs(mean - reference) * np.sqrt(spp / variance)
    erfc = np.vectorize(math.erfc)
    return erfc(z / math.sqrt(2.0))  # = 2 (1 - Phi(z))


def cases(folder):
    for scene in sorted(glob.glob(os.path.join(folder, "tests", "scenes", "*", "*.xml"))):
        stem = os.path.splitext(os.path.basename(scene))[0]
        if "_" not in stem:
            continue
        name, integrator = stem.rsplit("_", 1)
        refs = os.path.join(os.path.dirname(scene), "refs")
        reference = os.path.join(refs, name + "_ref_rgb.exr")
        variance = os.path.join(refs, name + "_ref_rgb_var.exr")
        if os.path.exists(reference) and os.path.exists(variance):
            yield scene, integrator, reference, variance


def run_case(args, scene, integrator, reference_path, variance_path):
    folder = os.path.basename(os.path.dirname(scene))
    label = f"{folder}/{os.path.basename(scene)}"
    reference = read_rgb(reference_path)
    variance = read_rgb(variance_path)
    pixels = reference.shape[0] * reference.shape[1]
    spp = max(1, int(args.budget) // pixels)
    out = os.path.join(args.out, os.path.splitext(os.path.basename(scene))[0] + ".exr")
    command = [args.binary, "render", scene, "--spp", str(spp), "-D", f"spp={spp}", "-D",
               f"integrator={integrator}", "--seed", str(args.seed), "-t", str(args.threads),
               "-q", "-o", out]
    done = subprocess.run(command, capture_output=True, text=True)
    row = {"scene": label, "integrator": integrator, "spp": spp}
    if done.returncode != 0:
        message = (done.stderr.strip() or done.stdout.strip()).splitlines()
        match = OUT_OF_SCOPE.search(done.stderr)
        row["outcome"] = "out of scope" if done.returncode == 2 and match else "error"
        row["message"] = message[0] if message else f"exit {done.returncode}"
        return row
    image = read_rgb(out)
    if image.shape != reference.shape:
        row["outcome"] = "error"
        row["message"] = f"resolution {image.shape[:2]} against the reference's {reference.shape[:2]}"
        return row
    p = z_test_p_values(to_xyz(image), spp, to_xyz(reference), to_xyz(variance))
    alpha = 1.0 - (1.0 - 0.01) ** (1.0 / pixels)
    passed_fraction = float(np.count_nonzero(p > alpha)) / p.size
    row.update({
        "outcome": "pass" if passed_fraction >= 0.9975 else "fail",
        "passed_fraction": passed_fraction,
        "min_p": float(p.min()),
        "alpha": alpha,
        "mean_ratio": float(image.mean() / reference.mean()) if reference.mean() > 0 else None,
        "rel_mse": float(rel_mse(image, reference)),
    })
    return row


def table(rows):
    lines = ["| scene | integrator | spp | outcome | pixel channels passing | min p | mean ratio | relMSE |",
             "|---|---|---:|---|---:|---:|---:|---:|"]
    for r in rows:
        if r["outcome"] in ("pass", "fail"):
            lines.append(f"| {r['scene']} | {r['integrator']} | {r['spp']} | {r['outcome']} | "
                         f"{100 * r['passed_fraction']:.2f}% | {r['min_p']:.2g} | "
                         f"{r['mean_ratio']:.4f} | {r['rel_mse']:.2e} |")
        else:
            lines.append(f"| {r['scene']} | {r['integrator']} | {r['spp']} | {r['outcome']} | "
                         f"{r.get('message', '')} | | | |")
    counts = {}
    for r in rows:
        counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
    lines.append("")
    lines.append(", ".join(f"{k}: {v}" for k, v in sorted(counts.items())))
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", help="a checkout of mitsuba-renderer/mitsuba-data")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--budget", type=float, default=2e6,
                        help="samples per image (Mitsuba's test: 2e6)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", default="", help="regular expression on the scene path")
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "mitsuba_render_tests"))
    parser.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for scene, integrator, reference, variance in cases(args.folder):
        if args.only and not re.search(args.only, scene):
            continue
        row = run_case(args, scene, integrator, reference, variance)
        rows.append(row)
        print(json.dumps(row), flush=True)
    text = table(rows)
    print(text)
    with open(os.path.join(args.out, "mitsuba_render_tests.json"), "w") as f:
        json.dump(rows, f, indent=1)
    with open(os.path.join(args.out, "mitsuba_render_tests.md"), "w") as f:
        f.write(text + "\n")


if __name__ == "__main__":
    main()
