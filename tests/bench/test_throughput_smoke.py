#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Smoke test of `bench/throughput.py`: two tiny path-tracer renders of cbox, no Mitsuba, no
profiler, and raw Embree from the bench_embree built beside the binary; the JSON must hold our
samples/s for each run, raw Embree's rates for single rays and for packets of 16 (every ray kind),
and the path tracer's share of each, and the printed report the lines scripts read. With each
path-tracer run, PSSMLT, GDPT and GDMLT render the same scene too (the script's default
--integrators); the JSON's "mlt_rates" must hold each one's rate and its ratio to the path
tracer's samples/s for each run and their medians, and the report their lines.

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
# The integrators throughput.py compares with the path tracer by default, and their rates' units.
UNITS = {"pssmlt": "mutations/s", "gdpt": "samples/s", "gdmlt": "proposals/s"}


def positive(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x) and x > 0


class ThroughputSmoke(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        """One run of the script (both tests read it)."""
        binary = os.environ.get("GDMLT_BINARY", os.path.join(ROOT, "build", "release", "gdmlt"))
        with tempfile.TemporaryDirectory(prefix="gdmlt_throughput_test_") as tmp:
            out_json = os.path.join(tmp, "throughput.json")
            cls.proc = subprocess.run(
                [sys.executable, os.path.join(ROOT, "bench", "throughput.py"), "--gdmlt", binary,
                 "--scene", os.path.join(ROOT, "scenes", "cbox.xml"), "--res", "32", "--spp", "4",
                 "--threads", "1", "--runs", "2", "--mitsuba", "off", "--embree-fraction", "none",
                 "--json", out_json],
                capture_output=True, text=True, timeout=300)
            cls.result = None
            if cls.proc.returncode == 0:
                with open(out_json) as f:
                    cls.result = json.load(f)

    def setUp(self):
        self.assertEqual(self.proc.returncode, 0, self.proc.stdout + self.proc.stderr)

    def test_reports_our_rate_and_both_raw_embree_rates(self):
        run, result = self.proc, self.result
        ours = result["gdmlt"]
        self.assertEqual(len(ours["samples_per_s"]), 2)
        self.assertTrue(all(positive(x) for x in ours["samples_per_s"]), ours)
        self.assertTrue(positive(ours["rays_per_sample"]), ours)

        raw = result["raw_embree"]
        self.assertNotIn("error", raw, raw)
        for form in ("rays_per_s", "packet_rays_per_s"):
            self.assertEqual(set(raw[form]), KINDS, form)
            self.assertTrue(all(positive(v) for v in raw[form].values()), raw[form])
        # The wavefront's camera packets are one pixel's samples flagged coherent: the packet
        # rate for camera rays is that form's, the other two are reported beside it.
        camera = raw["camera_packet_rays_per_s"]
        self.assertEqual(set(camera), {"camera", "camera_pixel", "camera_pixel_coherent"})
        self.assertTrue(all(positive(v) for v in camera.values()), camera)
        self.assertEqual(raw["packet_rays_per_s"]["camera"], camera["camera_pixel_coherent"])
        for share in ("path_share_of_raw", "path_share_of_raw_packets"):
            self.assertEqual(len(raw[share]), 2, share)
            self.assertTrue(all(positive(x) for x in raw[share]), raw[share])

        self.assertRegex(run.stdout, r"raw Embree \(bench_embree, 1 threads, single rays\): "
                                     r"camera [\d.]+, bounce [\d.]+, shadow [\d.]+ M rays/s")
        self.assertRegex(run.stdout, r"raw Embree \(bench_embree, 1 threads, packets of 16\): "
                                     r"camera [\d.]+, bounce [\d.]+, shadow [\d.]+ M rays/s")
        self.assertRegex(run.stdout, r"raw Embree camera packets \(.*\): camera [\d.]+, "
                                     r"camera_pixel [\d.]+, camera_pixel_coherent [\d.]+ M rays/s")
        self.assertRegex(run.stdout, r"path tracer at [\d.]+% of raw Embree \(")
        self.assertRegex(run.stdout, r"path tracer at [\d.]+% of raw Embree's packet rates")

    def test_reports_mlt_and_gdpt_rates_against_the_path_tracer(self):
        rates = self.result.get("mlt_rates")
        self.assertIsNotNone(rates, self.result.keys())
        self.assertEqual(set(rates), set(UNITS), rates.keys())
        number = r"[\d.]+(?:e[+-]\d+)?"
        per_run = []
        for name, unit in UNITS.items():
            r = rates[name]
            for key in ("rate", "ratio_to_path_samples_per_s"):
                self.assertEqual(len(r[key]), 2, (name, key))
                self.assertTrue(all(positive(x) for x in r[key]), (name, key, r[key]))
            for key in ("rate_median", "ratio_median"):
                self.assertTrue(positive(r[key]), (name, key, r[key]))
            self.assertEqual(r["unit"], unit, name)
            self.assertRegex(self.proc.stdout,
                             rf"\n{name} {unit}: median {number}  \(min {number}, max {number}, "
                             rf"n=2\); per run / path tracer samples/s: median {number}  "
                             rf"\(min {number}, max {number}, n=2\)\n")
            self.assertRegex(self.proc.stdout, rf"\n  {name} time \(medians\): ")
            per_run.append(rf"{name} {number} M {unit} \({number}x path tracer\)")
        for i in range(2):
            self.assertRegex(self.proc.stdout, rf"\n  run {i}: " + ", ".join(per_run) + "\n")


if __name__ == "__main__":
    unittest.main()
