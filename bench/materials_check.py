#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Checks the materials, textures and emitters against Mitsuba 3.

1. scenes/rough_metal_glass.xml at 64 spp against ../shared/references/rough_metal_glass.exr:
   relative MSE of gdmlt's render, averaged over --seeds renders, against Mitsuba's own 64 spp
   error (0.021, ../shared/references/README.md). Passes when the ratio is at most 1.5.

2. scenes/materials_envmap.xml (environment map, bitmap texture, plastic and rough plastic)
   against a Mitsuba 3 render of the same file, when a Python with `mitsuba` is available
   (--mitsuba-python, or this interpreter). Mitsuba renders a reference at --ref-spp and a
   second, independent render at --spp; gdmlt renders at --spp. Reported: the relative MSE of
   each against the reference and the per-channel means. gdmlt matches when its error is at
   most 1.5x Mitsuba's own at the same spp and the means agree to 1%.

   scalar_rgb needs no LLVM; llvm_ad_rgb is faster given DRJIT_LIBLLVM_PATH (LLVM >= 16).

--generate-assets rewrites the scene's small texture and environment map (deterministic).

  /usr/bin/python3 bench/materials_check.py --gdmlt build/release/gdmlt \\
      [--mitsuba-python /tmp/mi_venv/bin/python] [--variant scalar_rgb] [--seeds 3]
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import metrics  # noqa: E402

SHARED = os.path.join(os.path.dirname(ROOT), "shared")
MITSUBA_RELMSE_64SPP = 0.021  # ../shared/references/README.md
ENV_SCENE = os.path.join(ROOT, "scenes", "materials_envmap.xml")
ASSETS = os.path.join(ROOT, "scenes", "materials_envmap")

MITSUBA_RENDER = r"""
import sys, mitsuba as mi
mi.set_variant(sys.argv[1])
scene = mi.load_file(sys.argv[2], spp=int(sys.argv[4]), res=int(sys.argv[5]))
image = mi.render(scene, seed=int(sys.argv[6]))
mi.Bitmap(image).write(sys.argv[3])
"""


def generate_assets():
    """A 64 x 32 sky (gradient, a warm sun-like blob, a darker ground) as half-float EXR and a
    64 x 64 8-bit sRGB PNG tile pattern: small, smooth enough to compare at modest spp."""
    os.makedirs(ASSETS, exist_ok=True)
    w, h = 64, 32
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    uu, vv = np.meshgrid(u, v)
    sky = np.zeros((h, w, 3), np.float32)
    up = np.clip(1.0 - 2.0 * vv, 0.0, 1.0)  # 1 at the zenith, 0 at the horizon and below
    sky[..., 0] = 0.25 + 0.35 * up
    sky[..., 1] = 0.35 + 0.45 * up
    sky[..., 2] = 0.55 + 0.75 * up
    ground = vv > 0.5
    sky[ground] = np.array([0.12, 0.10, 0.08], np.float32)
    # Sun: u = 0.3, elevation ~35 degrees (v ~ 0.3), a few pixels wide, bright.
    d2 = ((uu - 0.3) * 2.0) ** 2 + (vv - 0.3) ** 2
    sun = np.exp(-d2 / (2 * 0.03 ** 2))
    sky += sun[..., None] * np.array([60.0, 50.0, 35.0], np.float32)
    spec = oiio.ImageSpec(w, h, 3, oiio.HALF)
    spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(os.path.join(ASSETS, "sky.exr"))
    out.open(os.path.join(ASSETS, "sky.exr"), spec)
    out.write_image(sky)
    out.close()

    t = 64
    x = (np.arange(t) + 0.5) / t
    xx, yy = np.meshgrid(x, x)
    tiles = ((np.floor(xx * 4) + np.floor(yy * 4)) % 2).astype(np.float32)
    colour_a = np.array([0.80, 0.75, 0.65], np.float32)
    colour_b = np.array([0.25, 0.35, 0.55], np.float32)
    tex = tiles[..., None] * colour_a + (1 - tiles[..., None]) * colour_b
    tex *= (0.85 + 0.15 * np.sin(2 * np.pi * 3 * xx))[..., None]  # a gradient inside tiles
    png = np.clip(np.round(np.where(tex <= 0.0031308, 12.92 * tex, 1.055 * tex ** (1 / 2.4) - 0.055) * 255), 0, 255)
    spec = oiio.ImageSpec(t, t, 3, oiio.UINT8)
    out = oiio.ImageOutput.create(os.path.join(ASSETS, "tiles.png"))
    out.open(os.path.join(ASSETS, "tiles.png"), spec)
    out.write_image(png.astype(np.uint8))
    out.close()
    for name in ("sky.exr", "tiles.png"):
        print(f"wrote {os.path.join(ASSETS, name)} ({os.path.getsize(os.path.join(ASSETS, name))} bytes)")


def render_gdmlt(gdmlt, scene, out, spp, seed, defines=()):
    cmd = [gdmlt, "render", scene, "-o", out, "--spp", str(spp), "--seed", str(seed), "--quiet"]
    for d in defines:
        cmd += ["-D", d]
    subprocess.run(cmd, check=True, capture_output=True)
    return metrics.read_rgb(out)


def check_rough_metal_glass(gdmlt, seeds, tmp):
    reference = metrics.read_rgb(os.path.join(SHARED, "references", "rough_metal_glass.exr"))
    scene = os.path.join(ROOT, "scenes", "rough_metal_glass.xml")
    errors = []
    for seed in range(seeds):
        image = render_gdmlt(gdmlt, scene, os.path.join(tmp, f"rmg_{seed}.exr"), 64, seed)
        errors.append(metrics.rel_mse(image, reference))
        print(f"  seed {seed}: relMSE {errors[-1]:.4f}  mean {image.mean(axis=(0, 1))}")
    mean = float(np.mean(errors))
    ratio = mean / MITSUBA_RELMSE_64SPP
    print(f"rough_metal_glass @64 spp: relMSE {mean:.4f} (Mitsuba {MITSUBA_RELMSE_64SPP}), "
          f"ratio {ratio:.2f} -> {'PASS' if ratio <= 1.5 else 'FAIL'}")
    print(f"  reference mean {reference.mean(axis=(0, 1))}")
    return ratio <= 1.5


def find_mitsuba_python(requested):
    candidates = [requested] if requested else [sys.executable]
    for python in candidates:
        if python and subprocess.run([python, "-c", "import mitsuba"], capture_output=True).returncode == 0:
            return python
    return None


def check_envmap_scene(gdmlt, python, variant, spp, ref_spp, res, tmp):
    def mitsuba(out, n, seed):
        script = os.path.join(tmp, "mitsuba_render.py")
        with open(script, "w") as f:
            f.write(MITSUBA_RENDER)
        subprocess.run([python, script, variant, ENV_SCENE, out, str(n), str(res), str(seed)], check=True)
        return metrics.read_rgb(out)

    reference = mitsuba(os.path.join(tmp, "env_ref.exr"), ref_spp, 1000)
    mitsuba_image = mitsuba(os.path.join(tmp, "env_mitsuba.exr"), spp, 7)
    ours = render_gdmlt(gdmlt, ENV_SCENE, os.path.join(tmp, "env_gdmlt.exr"), spp, 7, [f"res={res}"])
    e_ours, e_mitsuba = metrics.rel_mse(ours, reference), metrics.rel_mse(mitsuba_image, reference)
    m_ref, m_ours = reference.mean(axis=(0, 1)), ours.mean(axis=(0, 1))
    mean_ok = bool(np.all(np.abs(m_ours / m_ref - 1.0) < 0.01))
    ok = e_ours <= 1.5 * e_mitsuba and mean_ok
    print(f"materials_envmap ({res}x{res}): reference Mitsuba {variant} at {ref_spp} spp")
    print(f"  relMSE at {spp} spp: gdmlt {e_ours:.5f}, Mitsuba {e_mitsuba:.5f}, ratio {e_ours / e_mitsuba:.2f}")
    print(f"  mean RGB: reference {m_ref}, gdmlt {m_ours}, Mitsuba@{spp} {mitsuba_image.mean(axis=(0, 1))}")
    print(f"  -> {'PASS' if ok else 'FAIL'}")
    return ok


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--gdmlt", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    parser.add_argument("--seeds", type=int, default=3, help="gdmlt renders of rough_metal_glass")
    parser.add_argument("--mitsuba-python", default=None)
    parser.add_argument("--variant", default="scalar_rgb")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--ref-spp", type=int, default=2048)
    parser.add_argument("--res", type=int, default=128)
    parser.add_argument("--skip-rough-metal-glass", action="store_true")
    parser.add_argument("--generate-assets", action="store_true")
    args = parser.parse_args()
    if args.generate_assets:
        generate_assets()
        return 0
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        if not args.skip_rough_metal_glass:
            ok &= check_rough_metal_glass(args.gdmlt, args.seeds, tmp)
        python = find_mitsuba_python(args.mitsuba_python)
        if python is None:
            print("materials_envmap: skipped (no Python with `import mitsuba`; see --mitsuba-python)")
        else:
            ok &= check_envmap_scene(args.gdmlt, python, args.variant, args.spp, args.ref_spp, args.res, tmp)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
