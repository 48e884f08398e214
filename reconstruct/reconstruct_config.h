// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Every knob of the reconstructions, with its default and where the default comes from.
#include <optional>
#include <string>

namespace gdmlt::reconstruct {

enum class Method { l2, l1, cv };

/// "l2" | "l1" | "cv"; std::nullopt for anything else.
std::optional<Method> parse_method(const std::string& name);
std::string to_string(Method method);

/// The CLI's default coarse radius. Measured on 16 s renders (L1, then radii 2..32): on
/// caustic_glass_light radius 8 brought the image mean from x0.59 to x1.003 (GDPT) and from
/// x0.73 to x0.94 (GDMLT: its primal's own mean, b* being 6% off) and relMSE from 0.300 to
/// 0.069 (GDPT) and 0.212 to 0.188 (GDMLT); on cbox_glass_sphere relMSE went from 0.0103 to
/// 0.0086 (GDPT) and 0.0063 to 0.0061 (GDMLT). Radius 4 was best for GDPT, 16-32 for GDMLT
/// (its primal's noise is correlated over more pixels); 8 is within 25% of the best for both.
inline constexpr int kDefaultCoarseRadius = 8;
/// The CLI's default ReconstructConfig::huber_k for rendering: on GDPT renders at 16 s of the
/// four shared scenes it lowered L1's relMSE by 11-30% (three seeds on two of them), with the
/// mean unchanged (bench/reconstruct_cost.py, method "huber" against "l1").
inline constexpr double kDefaultHuber = 1.345;

struct ReconstructConfig {
    Method method = Method::l1;

    /// Screening weight of the primal term: the data term is alpha^2 * |x - p|^2 (L2) or
    /// alpha * |x - p| (L1). 0.2 is the G-PT / NVIDIA solver default (Kettunen et al. 2015:
    /// alpha = 0.2 means a data-term weight alpha^2 = 0.04 relative to gradients). Must be finite,
    /// >= 0.
    double alpha = 0.2;

    /// Start CG from the primal (true; Lehtinen 2013 / the NVIDIA solver do) or from zero (tests
    /// use this to make the solver do real work when the primal is already the answer).
    bool warm_start = true;

    // --- L2: preconditioned conjugate gradient -------------------------------------------------
    /// Upper bound on CG iterations for the L2 solve. The NVIDIA presets use 50 (L2D) and 500
    /// (L2Q) fixed iterations; we stop by residual instead and keep this as a safety cap.
    int cg_max_iterations = 500;
    /// Stop when |r_c| <= tolerance * |b_c| for every colour channel c (relative residual of the
    /// normal equations). 1e-3 is below visible error for images in [0, 1] (bench/ measures it).
    double cg_tolerance = 1e-3;

    // --- L1: iteratively reweighted least squares around the L2 solver ------------------------
    /// Outer iterations; 20 with rho0 = 0.05, gamma = 0.5 is the NVIDIA solver's default L1D
    /// preset (Kettunen et al. 2015).
    int irls_iterations = 20;
    double irls_rho0 = 0.05;
    double irls_gamma = 0.5;
    /// Floor of rho_k: weights 1/(|e| + rho) must never become infinite on exact fits.
    double irls_rho_min = 1e-6;
    /// CG budget of each inner solve (warm-started from the previous outer iterate, so a few
    /// iterations suffice; L1D uses 50 on a GPU, we use fewer and a tolerance to meet the time).
    int irls_cg_iterations = 25;
    double irls_cg_tolerance = 1e-3;
    /// Stop early when |J_k - J_{k-1}| <= tolerance * J_{k-1}, J the L1 objective. 0 disables.
    double l1_objective_tolerance = 1e-4;
    /// Huber instead of L1 where the noise is known (0: pure L1). A row whose variance layer
    /// gives sigma (RGB norm of its noise, sqrt(3 var)) costs r^2 / (2 delta) for |r| <= delta
    /// and |r| - delta / 2 beyond, delta = huber_k sigma (Huber 1964): residuals the noise
    /// explains are averaged as in L2 instead of being pulled to the median, outliers still
    /// count linearly. Its IRLS weight is 1 / max(|r|, delta) (L1's is 1 / |r|). 1.345 is the
    /// classic constant (95% of L2's efficiency under Gaussian noise). Rows without a variance
    /// stay L1, and so does the primal's data term (its "variance" may be the 1/sample_count
    /// model, which has no scale).
    double huber_k = 0.0;

    // --- Weighted control variates (Rousselle, Jarosz, Novak 2016) ----------------------------
    /// Jacobi-style iterations; 50 is the default of the public course code (Rousselle et al.
    /// 2016).
    int cv_iterations = 50;
    /// Regulariser of the inverse-variance weights, 1e-4 as in the course code.
    double cv_epsilon = 1e-4;
    /// Weight each estimate by its inverse variance when variances are known (else uniform).
    bool cv_use_variance = true;

    // --- Energy: the primal's coarse scales (reconstruct/coarse_correction.h) -----------------
    /// After any method: x += B_r(primal - x), B_r a blur of standard deviation about r pixels
    /// that keeps the image's sum. 0 (the library's default) leaves the method's image as is;
    /// the CLI's default for rendering is kDefaultCoarseRadius.
    int coarse_radius = 0;

    // --- Execution ----------------------------------------------------------------------------
    /// Pixels per reduction block. Dot products are summed per fixed block and the blocks in
    /// order, so results are bit-identical at any thread count. Changing it changes rounding.
    int block_size = 4096;
};

}  // namespace gdmlt::reconstruct
