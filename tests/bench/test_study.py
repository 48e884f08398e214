#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Unit tests of bench/study.py's report functions (table building, metrics, parsing of stats)
on small inputs whose answers are worked out by hand in each test."""
import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "bench"))
import metrics  # noqa: E402
import study  # noqa: E402


class Cells(unittest.TestCase):
    def test_missing_and_non_finite_values_print_as_a_dash(self):
        self.assertEqual(study.fmt(None), "-")
        self.assertEqual(study.fmt(float("nan")), "-")
        self.assertEqual(study.fmt(float("inf")), "-")

    def test_numbers_keep_four_significant_digits_and_integers_stay_integers(self):
        self.assertEqual(study.fmt(0.000123456), "0.0001235")
        self.assertEqual(study.fmt(12345.6), "1.235e+04")
        self.assertEqual(study.fmt(7), "7")
        self.assertEqual(study.fmt(np.int64(3)), "3")
        self.assertEqual(study.fmt(True), "yes")
        self.assertEqual(study.fmt("l1"), "l1")

    def test_a_table_has_a_header_a_rule_and_one_line_per_row(self):
        table = study.md_table(["a", "b"], [["x", 0.5], ["y", None]])
        self.assertEqual(table.splitlines(), ["| a | b |", "|---|---|", "| x | 0.5 |", "| y | - |"])

    def test_a_row_of_the_wrong_length_is_an_error(self):
        with self.assertRaises(ValueError):
            study.md_table(["a", "b"], [["only one"]])

    def test_median_and_ratio_skip_what_is_missing(self):
        self.assertEqual(study.median([3.0, None, 1.0, float("nan"), 2.0]), 2.0)
        self.assertIsNone(study.median([None]))
        self.assertIsNone(study.ratio(1.0, 0.0))
        self.assertEqual(study.ratio(1.0, 4.0), 0.25)


class Metrics(unittest.TestCase):
    def test_rel_mse_divides_by_the_squared_reference_plus_a_hundredth(self):
        reference = np.array([[[0.0, 1.0, 2.0]]])
        image = np.array([[[1.0, 1.0, 1.0]]])
        # (1/0.01 + 0/1.01 + 1/4.01) / 3
        self.assertAlmostEqual(metrics.rel_mse(image, reference), (100.0 + 1.0 / 4.01) / 3.0)

    def test_reference_noise_is_a_quarter_of_the_halves_relative_difference(self):
        truth = np.ones((4, 4, 3))
        a, b = truth + 0.1, truth - 0.1
        # mean is 1: (0.2^2 / 1.01) / 4
        self.assertAlmostEqual(study.reference_noise(a, b), 0.04 / 1.01 / 4.0)
        self.assertEqual(study.reference_noise(truth, truth), 0.0)

    def test_similarity_is_the_mean_difference_variance_over_the_primal_variance(self):
        primal = np.ones((2, 2))
        self.assertAlmostEqual(study.difference_variance_ratio(primal, [2 * primal, np.zeros((2, 2))]), 1.0)
        self.assertAlmostEqual(study.difference_variance_ratio(primal, [primal, primal]), 1.0)
        self.assertIsNone(study.difference_variance_ratio(np.zeros((2, 2)), [primal]))

    def test_gradient_error_ratio_is_zero_for_exact_differences_along_either_axis(self):
        yy, xx = np.mgrid[0:4, 0:5].astype(float)
        primal = xx ** 2 + 10 * yy  # I(x + 1) - I(x) = 2x + 1, I(y + 1) - I(y) = 10
        dx, dy = 2 * xx + 1, np.full((4, 5), 10.0)
        ones, zeros = np.ones((4, 5)), np.zeros((4, 5))
        self.assertEqual(study.gradient_error_ratio(dx, ones, primal, zeros, 1), 0.0)
        self.assertEqual(study.gradient_error_ratio(dy, ones, primal, zeros, 0), 0.0)
        # Swapped axes are wrong differences, which the metric must see.
        self.assertGreater(study.gradient_error_ratio(dy, ones, primal, zeros, 1), 10.0)

    def test_gradient_error_ratio_is_the_squared_bias_over_both_estimates_variances(self):
        primal = np.zeros((3, 3))
        dx = np.full((3, 3), 0.5)
        # Every edge off by 0.5: variance 0.25 of the difference alone gives 1; with the primal's
        # 0.125 per pixel (two per edge) 0.25 / 0.5. The last column has no edge along x, and
        # a non-finite edge (NaN: no edge in the layer) does not count.
        self.assertAlmostEqual(study.gradient_error_ratio(dx, np.full((3, 3), 0.25), primal, np.zeros((3, 3)), 1), 1.0)
        self.assertAlmostEqual(study.gradient_error_ratio(dx, np.full((3, 3), 0.25), primal,
                                                          np.full((3, 3), 0.125), 1), 0.5)
        dx[0, 0] = np.nan
        self.assertAlmostEqual(study.gradient_error_ratio(dx, np.full((3, 3), 0.0625), primal, np.zeros((3, 3)), 1), 4.0)

    def test_unbiased_noisy_differences_score_about_one_and_biased_ones_more(self):
        # 200x200 pixels, seed 3: noisy primal (variance 0.04) and differences (variance 0.01)
        # of the same smooth image. The ratio of sums over 39800 edges has a relative standard
        # deviation of about sqrt(2 / 39800) = 0.7%: 1 +- 0.05 is seven sigmas; a bias of 0.2
        # per edge adds 0.04 / 0.09 = 0.44.
        rng = np.random.default_rng(3)
        yy, xx = np.mgrid[0:200, 0:200] / 200.0
        truth = np.sin(3 * xx) + yy
        primal = truth + rng.normal(0, 0.2, truth.shape)
        dx = np.zeros_like(truth)
        dx[:, :-1] = truth[:, 1:] - truth[:, :-1]
        noisy = dx + rng.normal(0, 0.1, truth.shape)
        var_d, var_p = np.full(truth.shape, 0.01), np.full(truth.shape, 0.04)
        self.assertAlmostEqual(study.gradient_error_ratio(noisy, var_d, primal, var_p, 1), 1.0, delta=0.05)
        self.assertGreater(study.gradient_error_ratio(noisy + 0.2, var_d, primal, var_p, 1), 1.3)

    def test_injected_outliers_hit_the_requested_number_of_pixels_and_leave_the_input_alone(self):
        image = np.ones((10, 20, 3))
        spiked = study.inject_outliers(image, 0.01, 50.0, np.random.default_rng(0))
        changed = np.any(spiked != image, axis=2)
        self.assertEqual(int(changed.sum()), 2)  # 1% of 200 pixels
        np.testing.assert_array_equal(spiked[changed], 51.0)  # 1 + 50 x mean |image|
        np.testing.assert_array_equal(image, 1.0)
        self.assertEqual(int(np.any(study.inject_outliers(image, 0.0, 5.0, np.random.default_rng(0)) != image,
                                    axis=2).sum()), 1)  # at least one


class Parsing(unittest.TestCase):
    def test_the_reconstruct_summary_line_gives_solve_and_setup_seconds(self):
        line = ("reconstruct l1: 15 iterations (59 CG), relative residual 0.000649, 0 edges dropped, "
                "0 missing primal pixels, 0.013 s (setup 0.002 s) -> /tmp/s_r.exr")
        self.assertEqual(study.parse_reconstruct_seconds(line), (0.013, 0.002))
        with self.assertRaises(ValueError):
            study.parse_reconstruct_seconds("reconstruct l1: done")

    def test_what_ran_reads_machinery_work_and_time_shares(self):
        stats = {"machinery": {"manifold_solver": False, "shift_mappings": True, "light_tracing": False,
                               "markov_chains": True, "why": "no specular surface"},
                 "render_s": 4.0, "bootstrap_s": 0.4, "reconstruct_s": 1.0, "very_direct_s": None,
                 "rays": {"total": 1000},
                 "shifts": {"total": 200, "manifold_walks": 0, "manifold_newton_iterations": 0,
                            "by_status": {"ok": 150, "occluded": 50}},
                 "nonfinite_samples_dropped": 3}
        row = study.what_ran(stats)
        self.assertFalse(row["manifold_solver"])
        self.assertTrue(row["shift_mappings"] and row["markov_chains"])
        self.assertEqual(row["why"], "no specular surface")
        self.assertEqual((row["rays"], row["shifts"], row["manifold_walks"], row["nonfinite_dropped"]),
                         (1000, 200, 0, 3))
        self.assertAlmostEqual(row["shift_ok_rate"], 0.75)
        self.assertEqual(row["time_shares"], {"bootstrap_s": 0.1, "reconstruct_s": 0.25})

    def test_what_ran_of_a_path_tracer_has_no_shifts(self):
        row = study.what_ran({"render_s": 1.0, "samples_per_s": 10.0})
        self.assertEqual(row["shifts"], 0)
        self.assertIsNone(row["shift_ok_rate"])
        self.assertFalse(row["manifold_solver"])

    def test_rate_is_proposals_per_chain_second_for_chains_else_samples_per_second(self):
        self.assertEqual(study.rate_of("gdmlt", {"mutations": 100, "chains_s": 4.0, "samples_per_s": 1.0}), 25.0)
        self.assertEqual(study.rate_of("path", {"samples_per_s": 7.0}), 7.0)


if __name__ == "__main__":
    unittest.main()
