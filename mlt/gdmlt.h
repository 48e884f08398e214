// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Gradient-domain Metropolis light transport (Lehtinen, Karras, Laine, Aittala, Durand, Aila
// 2013) in primary sample space, with the shifts of manifold/ (reconnection, half-vector copy,
// replay, and the manifold shift through specular chains of Manzi et al. 2014).
//
// A chain state u is a base path through pixel i (its first two primary samples are the film
// position) and its shifts to i's neighbours (a NeighbourSet, the lattice by default). Per
// neighbour link k the state carries the MIS-weighted difference D_k(u) (mlt/gradient_sample.h)
// and the chain's target is
//     f*(u) = s_i sum_k Y(|D_k(u)|) + w * Y(C(u))                                     (GDMLT eq. 9)
// with C the base's primal contribution, |.| per colour channel, Y the luminance, w the
// primal weight and s_i = (i's lattice link count) / (i's link count), 1 on the lattice (a
// pixel with many ADAP links would otherwise draw the chains by its link count). f* > 0 wherever C
// or any D_k is non-zero, so the chain covers everything it splats. Splats (chain runner, Kelemen
// weights with b* = E_u[f*]): C into the pixel's primal, D_k into its edge (with the sign of the
// edge's orientation). The primal, the differences and b* thus share one chain; the screened
// Poisson solve turns them into the image. Very direct light (emitters seen from the camera) is
// never shifted: a short path-traced pass renders it into its own layer, added after the solve.
#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include "core/image/gradient_buffers.h"
#include "core/image/neighbour_set.h"
#include "core/scene/scene.h"
#include "manifold/shift.h"
#include "mlt/chain_runner.h"
#include "mlt/chain_settings.h"
#include "mlt/mutation.h"

namespace gdmlt::mlt {

/// The shared chain knobs (mutations_per_pixel: proposals, each tracing the base path and one
/// offset per neighbour, 16 by default; chains: 0 = one per 1024 proposals unidirectional
/// (1024 at 256^2 pixels), one per 4096 bidirectional (256), 64 .. 4096. 64 chains left a chain
/// brightness spread of 0.63 on cbox_glass_sphere at 16 s, too few to average their correlated
/// errors. Unidirectional, 1024 against 256 chains at 16 s: cbox_glass_sphere 0.0049 / 0.0043 /
/// 0.0047 against 0.0059 / 0.0072 / 0.0054 (seeds 0-2), rough_metal_glass 0.0032 / 0.0034
/// against 0.0037 / 0.0038, cbox 0.00030 / 0.00022 against 0.00023 / 0.00025 (a tie);
/// bidirectional on caustic_glass_light 1024 was worse: 0.127 / 0.040 / 0.047 against 0.050 /
/// 0.021 / 0.043) and GDMLT's own.
struct GdmltSettings : MarkovChainSettings {
    GdmltSettings() {
        mutations_per_pixel = 16.0;
        // Large-step probability. Measured at 16 s, relMSE of the final image (seeds 0-2, and
        // 0-1 in a second run), p_large 0.3 / 0.5 / 0.7 / 0.85: caustic_glass_light 0.17-0.21 /
        // 0.105-0.123 / 0.073-0.096 / 0.062-0.097, cbox_glass_sphere 0.0054-0.0062 /
        // 0.0050-0.0080 / 0.0041-0.0063 / 0.0050-0.0060. GDMLT's error is mostly low-frequency
        // (whole regions too bright or dark where a chain lingered: its target sum |D_k| is
        // peakier than PSSMLT's luminance and a proposal costs ~14 PSSMLT mutations, so each
        // chain makes few); large steps decorrelate the chains and are themselves an
        // independent estimator in Kelemen's MIS. PSSMLT keeps 0.3.
        mutation.p_large = 0.7;
    }

    /// The bootstrap grows until b*'s standard error is below this fraction of b* (up to 16x
    /// bootstrap_samples, and with a time budget within a tenth of it): the whole image's
    /// brightness is b*'s. max_depth -1 is capped at kUnboundedDepthCap.
    double bootstrap_relative_error = 0.01;
    manifold::ShiftKind shift = manifold::ShiftKind::Auto;
    /// w in f* = sum_k Y(|D_k|) + w Y(C). Measured at 16 s (2 seeds each, cbox_glass_sphere /
    /// caustic_glass_light): w = 0.25, 1, 4 gave final relMSEs within each other's seed spread,
    /// but the primal layer's relMSE was 1.3-1.5x lower at w = 1 than at 0.25 (the primal
    /// carries the image's low frequencies and its energy), and no better at 4.
    double primal_weight = 1.0;
    /// The primal of every pixel from its own base paths and from the offsets of its
    /// neighbours' (G-PT's MIS between pixels), instead of from its own base paths only.
    /// Measured at 16 s, seeds 0-2: the primal layer's relMSE 2.2-2.7x lower on
    /// cbox_glass_sphere and 1.6-2.1x on caustic_glass_light, but the final image's no better
    /// (medians 0.0066 vs 0.0065 and 0.198 vs 0.173): the reconstruction takes only the
    /// primal's coarse scales, where its noise averages out anyway. Off by default.
    bool primal_from_offsets = false;
    /// f* weighs a pixel's differences by its lattice link count over its link count (1 on the
    /// lattice), so that a pixel with more neighbours (ADAP) does not draw more of the chains'
    /// time for it (GradientTarget::difference_scale).
    bool normalise_link_count = true;
    /// Base paths are bidirectional samples (camera and light subpaths, every strategy, as
    /// `pssmlt --bidirectional`), shifted as G-BDPT shifts them
    /// (sample_bidirectional_gradients): light tracing is not shifted and joins the very direct
    /// layer.
    bool bidirectional = false;
    /// With bidirectional: shift light tracing too (to the neighbours of the pixel it lands
    /// on; sample_bidirectional_gradients), instead of adding it unshifted after the solve.
    bool shift_light_tracing = false;
    /// With bidirectional: the factor c of light tracing's density in the MIS weights over the
    /// strategies (BdptConnectionInput::light_tracing_scale). Unshifted light tracing keeps
    /// its noise through the solve while the other strategies' noise is reduced by it, so
    /// c < 1 moves light from the first to the second.
    double light_tracing_mis = 1.0;
    /// With bidirectional (and light tracing unshifted): light tracing's weighted share comes
    /// from a pass of its own before the chains (render_ptracer with BDPT's MIS weights over
    /// the same strategies, PtracerWeights) instead of from the chain's states, and the chain
    /// targets the other strategies only. The pass's pixels are independent, a chain's splats
    /// are not. Measured on caustic_glass_light at 16 s (seeds 0-4, medians; light tracing
    /// carries 40% of the light there): relMSE 0.041 against 0.062-0.076 with light tracing
    /// from the chains (whose unshifted light tracing layer held 70% of the final error; the
    /// pass's at 4 s had a third of that variance), and against GDPT's 0.049 in the same run.
    bool light_tracing_pass = true;
    /// With a time budget: the fraction of it the light tracing pass takes. 0.3 balances the
    /// two variances measured at 0.25 and 0.5 (each falls as its share of the time grows);
    /// 0.5 gave seeds from 0.025 to 0.071. Moving light to the pass with
    /// light_tracing_mis = 3 did not help (0.055 / 0.039 at 0.3 / 0.5) and made b's error
    /// worse.
    double light_tracing_share = 0.3;
    /// Without a time budget: the pass's light paths per pixel.
    int light_tracing_spp = 16;
    /// The share of the sampling budget given to gradient-domain path tracing (GDPT: independent
    /// samples, stratified per pixel) beside the chains; both estimate the same primal and
    /// differences, and their layers are combined slot by slot with inverse-variance weights
    /// (core/image/combine_buffers.h). < 0: auto: a pilot of each (pilot_share of the budget),
    /// then the rest to the one with less noise for its cost (BudgetSplit). 0: chains only
    /// (GDMLT as Lehtinen et al. built it); 1: GDPT only. Bidirectional sampling runs chains
    /// only (GDPT's samples are unidirectional and its layers not the same).
    double gdpt_share = -1.0;
    /// Auto: each pilot's share of the sampling budget.
    double pilot_share = 0.1;
    /// Radius of the window whose variances weigh a slot in the combination.
    int combine_radius = 3;
    /// Samples per pixel of the very direct pass (camera rays only, about 2% of a 16 s render
    /// at 256^2; fewer leave visible anti-aliasing noise on the edges of lights).
    int very_direct_samples = 64;
};

/// How the sampling budget was split between the chains and GDPT (GdmltSettings::gdpt_share).
struct BudgetSplit {
    std::string mode;      // "auto" or "share"
    std::string decision;  // "chains", "gdpt" or "both"
    std::string reason;
    /// Auto: each pilot's noise (sum of variance over I^2 + 0.01 on slots both know), its
    /// efficiency 1 / (noise x cost), cost in cost_unit ("s" with a time budget, else "rays").
    double gdpt_noise = 0.0, chain_noise = 0.0;
    double gdpt_efficiency = 0.0, chain_efficiency = 0.0;
    std::uint64_t slots_compared = 0;
    std::string cost_unit;
    double gdpt_s = 0.0;
    std::uint64_t gdpt_samples = 0;
    /// The parts combined, in order, and each one's mean weight over pixels and edges.
    std::vector<std::string> parts;
    std::vector<double> primal_weights, difference_weights;
};

/// The chain runner's statistics plus GDMLT's own.
struct GdmltStats : ChainStats {
    BudgetSplit split;
    double very_direct_s = 0.0;
    /// The light tracing pass (GdmltSettings::light_tracing_pass): its time and light paths.
    double light_tracing_s = 0.0;
    std::uint64_t light_paths = 0;
};

struct GdmltOutput {
    /// primal, dx, dy (+ extra edges for a non-lattice set) with their variance layers (batch
    /// means, or the combination's when GDPT passes ran), very_direct (with bidirectional
    /// sampling also the light tracing strategies: everything not shifted).
    GradientBuffers buffers;
    /// Chain states per pixel relative to a uniform sampler (1 = as many as uniform).
    Image sample_density;
    GdmltStats stats;
};

/// The screened Poisson solve's primal weight alpha for GDMLT renders (GDPT keeps the
/// reconstruction's default 0.2). GDMLT's primal comes from the same chain as its differences,
/// so it adds no independent information locally, and its errors are low-frequency, which the
/// coarse correction takes from the primal anyway. Measured on the same 16 s raw files
/// (p_large 0.7, seeds 0-2), alpha 0.05 vs 0.2: caustic_glass_light 0.081 / 0.073 / 0.076 vs
/// 0.087 / 0.073 / 0.082, cbox_glass_sphere 0.0050 / 0.0054 / 0.0039 vs 0.0055 / 0.0057 /
/// 0.0041; 0.4 and 0.8 were worse still, 0.1 in between.
inline constexpr double kGdmltReconstructAlpha = 0.05;

/// alpha for a render whose layers include GDPT passes (BudgetSplit::parts): their primal is
/// an independent estimate, and the screened Poisson solve should trust it as GDPT's does (the
/// reconstruction's default 0.2). Re-solving the auto split's 16 s renders (seed 0) with 0.2
/// instead of 0.05: materials_envmap 0.00098 -> 0.00022, rough_metal_glass 0.00106 -> 0.00102,
/// cbox_glass_sphere 0.00225 -> 0.00214, cbox 0.000087 -> 0.000086.
inline constexpr double kCombinedReconstructAlpha = 0.2;

/// The alpha for the layers a render produced: kGdmltReconstructAlpha when they come from
/// chains alone, kCombinedReconstructAlpha when a GDPT pass is among them.
double reconstruct_alpha(const BudgetSplit& split);

/// Renders with the lattice neighbours.
GdmltOutput render_gdmlt(
    const Scene& scene, const GdmltSettings& settings, const std::atomic<bool>* cancel = nullptr,
    const std::function<void(double fraction, double elapsed_s)>& progress = {});

/// Renders with any neighbour set over the crop window (its size must be the crop's).
GdmltOutput render_gdmlt(
    const Scene& scene, const GdmltSettings& settings, const NeighbourSet& neighbours,
    const std::atomic<bool>* cancel = nullptr,
    const std::function<void(double fraction, double elapsed_s)>& progress = {});

/// `--bidirectional auto`: whether a scene calls for bidirectional samples. They pay where the
/// light leaves its emitters through smooth (delta) surfaces, a light in a glass shell or behind
/// a lens: next-event estimation cannot connect through such a surface, so unidirectional
/// paths find that light only by chance, while light tracing and connections carry it.
/// Measured at 16 s (5 seeds, medians): on caustic_glass_light (its light in a glass sphere:
/// fraction 1) bidirectional GDMLT 0.041 against unidirectional 0.095; on cbox_glass_sphere
/// (a light in the ceiling: fraction ~0) unidirectional 0.0066 against 0.0084.
struct BidirectionalChoice {
    bool bidirectional = false;
    /// Of `rays` rays sampled leaving the emitters (as light subpaths start), the fraction
    /// whose first hit is a delta surface; bidirectional when at least kThreshold.
    double specular_first_hit_fraction = 0.0;
    int rays = 0;
    static constexpr double kThreshold = 0.5;
};
BidirectionalChoice choose_bidirectional(const Scene& scene);

/// Reads the knobs of a <integrator type="gdmlt"> element: the PSSMLT names (p_large,
/// mutation_size_low/high, image_mutation_size, chains, bootstrap_samples, mutations_per_pixel,
/// kelemen_style_weights) plus primal_weight, very_direct_samples, bootstrap_relative_error.
/// Unknown properties throw InputError with the location.
GdmltSettings gdmlt_settings_from_scene(const IntegratorSettings& integrator);

/// Throws InputError (at `loc`) when a knob is out of range.
void validate_gdmlt_settings(const GdmltSettings& settings, const FileLoc& loc);

}  // namespace gdmlt::mlt
