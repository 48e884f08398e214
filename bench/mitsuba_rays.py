#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Mitsuba 3's ray rate on a scene file, for bench_embree's `random` and `random_test` kinds.

The rays follow bench_embree.cpp's distribution (not its exact samples): origins uniform in the
middle 80% of the scene's bounding box per axis, directions uniform on the sphere, unbounded.
They are traced as one wavefront by `Scene.ray_intersect_preliminary` (nearest hit: what
bench_embree's `random` does) and by `Scene.ray_test` (any hit: `random_test`), each timed
`--repeats` times after a warm-up that compiles the kernels; the median rate is printed in
M rays/s, the unit of bench_embree's items_per_second.

Run it under an interpreter that can import mitsuba (e.g. a venv with `pip install mitsuba`):

    /tmp/mi_venv/bin/python bench/mitsuba_rays.py scenes/cbox_glass_sphere.xml --threads 2

and compare, in the same session, with

    GDMLT_BENCH_SCENE=scenes/cbox_glass_sphere.xml build/release/bench/bench_embree \\
        --benchmark_filter='random' --benchmark_min_time=1
"""
import argparse
import statistics
import sys
import time


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="Mitsuba XML scene file")
    parser.add_argument("--variant", default="llvm_ad_rgb",
                        help="Mitsuba variant (llvm_* trace a wavefront in parallel)")
    parser.add_argument("--threads", type=int, default=2, help="Dr.Jit worker threads")
    parser.add_argument("--rays", type=int, default=1 << 21, help="rays per wavefront")
    parser.add_argument("--repeats", type=int, default=5, help="timed wavefronts per query")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    dr.set_thread_count(args.threads)
    scene = mi.load_file(args.scene)
    bbox = scene.bbox()
    lo, size = bbox.min, bbox.max - bbox.min

    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(args.seed, args.rays)
    u = mi.Vector3f(sampler.next_1d(), sampler.next_1d(), sampler.next_1d())
    origin = lo + size * (0.1 + 0.8 * u)
    direction = mi.warp.square_to_uniform_sphere(sampler.next_2d())
    ray = mi.Ray3f(origin, direction)
    dr.eval(ray)

    def rate(query) -> float:
        result = query()
        dr.eval(result)  # warm-up: kernel compilation
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            result = query()
            dr.eval(result)
            dr.sync_thread()
            times.append(time.perf_counter() - start)
        return args.rays / statistics.median(times) / 1e6

    intersect = rate(lambda: scene.ray_intersect_preliminary(ray).t)
    test = rate(lambda: scene.ray_test(ray))
    print(f"mitsuba {mi.__version__} {args.variant}, {args.threads} threads, {args.rays} rays: "
          f"random {intersect:.1f} M rays/s, random_test {test:.1f} M rays/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
