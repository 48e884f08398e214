#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Smoke test of `bench/throughput.py`: two tiny path-tracer renders of cbox, no Mitsuba, no
profiler, and raw Embree from the bench_embree built beside the binary; the JSON must hold our
samples/s for each run, raw Embree's rates for single rays and for packets of 16 (every ray kind),
and the path tracer's share of each, and the printed report the lines scripts read.

A smoke test, not a benchmark: it asserts that every number was measured and is finite and
positive, never how large it is (that depends on the machine).

    GDMLT_BINARY=build/release/gdmlt tests/bench/test_throughput_smoke.py
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
KINDS = {"camera", "bounce", "shadow"}


def positive(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x) and x > 0


class ThroughputSmoke(unittest.TestCase):
    def test_reports_our_rate_and_both_raw_embree_rates(self):
        binary = os.environ.get("GDMLT_BINARY", os.path.join(ROOT, "build", "release", "gdmlt"))
        with tempfile.TemporaryDirectory(prefix="gdmlt_throughput_test_") as tmp:
            out_json = os.path.join(tmp, "throughput.json")
            run = subprocess.run(
                [sys.executable, os.path.join(ROOT, "bench", "throughput.py"), "--gdmlt", binary,
                 "--scene", os.path.join(ROOT, "scenes", "cbox.xml"), "--res", "32", "--spp", "4",
                 "--threads", "1", "--runs", "2", "--mitsuba", "off", "--embree-fraction", "none",
                 "--json", out_json],
                capture_output=True, text=True, timeout=300)
            self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
            with open(out_json) as f:
                result = json.load(f)

        ours = result["gdmlt"]
        self.assertEqual(len(ours["samples_per_s"]), 2)
        self.assertTrue(all(positive(x) for x in ours["samples_per_s"]), ours)
        self.assertTrue(positive(ours["rays_per_sample"]), ours)

        raw = result["raw_embree"]
        self.assertNotIn("error", raw, raw)
        for form in ("rays_per_s", "packet_rays_per_s"):
            self.assertEqual(set(raw[form]), KINDS, form)
            self.assertTrue(all(positive(v) for v in raw[form].values()), raw[form])
        for share in ("path_share_of_raw", "path_share_of_raw_packets"):
            self.assertEqual(len(raw[share]), 2, share)
            self.assertTrue(all(positive(x) for x in raw[share]), raw[share])

        self.assertRegex(run.stdout, r"raw Embree \(bench_embree, 1 threads, single rays\): "
                                     r"camera [\d.]+, bounce [\d.]+, shadow [\d.]+ M rays/s")
        self.assertRegex(run.stdout, r"raw Embree \(bench_embree, 1 threads, packets of 16\): "
                                     r"camera [\d.]+, bounce [\d.]+, shadow [\d.]+ M rays/s")
        self.assertRegex(run.stdout, r"path tracer at [\d.]+% of raw Embree \(")
        self.assertRegex(run.stdout, r"path tracer at [\d.]+% of raw Embree's packet rates")


if __name__ == "__main__":
    unittest.main()
