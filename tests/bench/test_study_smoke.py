#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Smoke test of `bench/study.py --quick`: a tiny scene (cbox at 24x24), tiny budgets, no Mitsuba
and no ../shared (the study makes its own reference), every section; then the report must hold
all six sections, each with measured numbers, its figures, and the JSON every section's data.

    GDMLT_BINARY=build/release/gdmlt tests/bench/test_study_smoke.py
"""
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import study  # noqa: E402


def tiny_study(tmp):
    """The study command on cbox at 24x24 with tiny budgets, writing below `tmp`."""
    binary = os.environ.get("GDMLT_BINARY", os.path.join(ROOT, "build", "release", "gdmlt"))
    return [sys.executable, os.path.join(ROOT, "bench", "study.py"), "--quick", "--binary", binary,
            "--scenes", os.path.join(ROOT, "scenes", "cbox.xml"), "--times", "0.3", "--define", "res=24",
            "--no-mitsuba", "--out", os.path.join(tmp, "study"), "--reference-cache", os.path.join(tmp, "refs"),
            "--reference-spp", "32", "--timing-res", "48", "--bench-min-time", "0.002"]


class QuickStudyOnATinyScene(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.out = os.path.join(cls.tmp.name, "study")
        cls.proc = subprocess.run(tiny_study(cls.tmp.name), capture_output=True, text=True)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def setUp(self):
        self.assertEqual(self.proc.returncode, 0, self.proc.stdout[-3000:] + self.proc.stderr[-3000:])

    def sections(self):
        with open(os.path.join(self.out, "report.md")) as f:
            report = f.read()
        parts = re.split(r"^## (\d)\. .*$", report, flags=re.M)
        return {int(parts[i]): parts[i + 1] for i in range(1, len(parts), 2)}

    def test_the_report_has_the_six_sections_in_order(self):
        sections = self.sections()
        self.assertEqual(sorted(sections), [1, 2, 3, 4, 5, 6])
        with open(os.path.join(self.out, "report.md")) as f:
            headings = re.findall(r"^## (\d)\. (.*)$", f.read(), flags=re.M)
        self.assertEqual([(int(n), t) for n, t in headings], sorted(study.SECTION_TITLES.items()))

    def test_every_section_has_a_table_of_measured_numbers(self):
        number = re.compile(r"\| -?\d+(\.\d+)?(e[-+]\d+)? \|")
        for n, text in self.sections().items():
            rows = [line for line in text.splitlines() if line.startswith("| ") and number.search(line)]
            self.assertTrue(rows, f"section {n} has no table row with a number:\n{text[:2000]}")

    def test_every_figure_the_report_names_exists(self):
        with open(os.path.join(self.out, "report.md")) as f:
            figures = re.findall(r"!\[[^]]*\]\(([^)]+)\)", f.read())
        self.assertGreaterEqual(len(figures), 6)  # curves, crops, knobs, shifts, edges, shares
        for name in figures:
            path = os.path.join(self.out, name)
            self.assertTrue(os.path.isfile(path) and os.path.getsize(path) > 1000, name)

    def test_the_json_holds_each_sections_data_and_the_reference_made_for_it(self):
        with open(os.path.join(self.out, "study.json")) as f:
            data = json.load(f)
        self.assertEqual(sorted(data["sections"]), ["1", "2", "3", "4", "5", "6"])
        runs = data["sections"]["1"]["runs"]
        self.assertEqual(sorted({r["integrator"] for r in runs}), sorted(study.INTEGRATORS))
        for r in runs:
            self.assertGreater(r["rel_mse"], 0.0)
            self.assertGreater(r["mean_ratio"], 0.5)
        shifts = data["sections"]["3"]["rows"]
        self.assertEqual([r["family"] for r in shifts], study.SHIFT_FAMILIES)
        for r in shifts:
            self.assertGreater(r["success"], 0.0)
            self.assertGreater(r["round_trip"], 0.9)
            self.assertGreater(r["similarity"], 0.0)
        # No ../shared reference at 24x24: the study made one with our path tracer.
        reference = data["references"]["cbox"]
        self.assertIn("gdmlt path tracer", reference["made_by"])
        self.assertGreater(reference["noise_rel_mse"], 0.0)
        # cbox is diffuse only: no manifold walk anywhere (section 6 says so, one row per integrator).
        what_ran = data["sections"]["6"]["rows"]
        self.assertEqual(sorted(r["integrator"] for r in what_ran), sorted(study.INTEGRATORS))
        self.assertTrue(any(r["shifts"] > 0 for r in what_ran))  # gdpt and gdmlt shifted
        for row in what_ran:
            self.assertFalse(row["manifold_solver"], row)
            self.assertEqual(row["manifold_walks"], 0, row)


class ACtrlCDuringTheStudy(unittest.TestCase):
    def test_still_writes_the_sections_that_finished_and_exits_130(self):
        with tempfile.TemporaryDirectory() as tmp:
            # Its own process group, as a terminal's Ctrl-C reaches the script and its gdmlt
            # child alike; SIGINT restored to the default in case this test runs with it
            # ignored (a background job), which would keep Python from raising KeyboardInterrupt.
            proc = subprocess.Popen(tiny_study(tmp) + ["--sections", "1", "2"], stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True, start_new_session=True,
                                    preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
            log = []
            for line in proc.stdout:
                log.append(line)
                if "section 2:" in line:
                    break
            time.sleep(1.0)  # inside section 2's renders (about 20 of them, and a benchmark)
            os.killpg(proc.pid, signal.SIGINT)
            rest, _ = proc.communicate(timeout=120)
            output = "".join(log) + rest
            self.assertEqual(proc.returncode, 130, output[-3000:])
            with open(os.path.join(tmp, "study", "report.md")) as f:
                report = f.read()
            self.assertIn("Incomplete: interrupted (Ctrl-C) during section 2", report)
            self.assertRegex(report, r"(?m)^## 1\. ")
            self.assertNotRegex(report, r"(?m)^## 2\. ")
            with open(os.path.join(tmp, "study", "study.json")) as f:
                data = json.load(f)
            self.assertEqual(sorted(data["sections"]), ["1"])
            self.assertTrue(data["sections"]["1"]["runs"])


if __name__ == "__main__":
    unittest.main()
