// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// One base path and its shifts to a pixel's neighbours: the estimator both gradient-domain
// integrators share (GDPT draws base paths per pixel, GDMLT from its Markov chain).
//
// For a base path x through pixel i and a neighbour j = i + d, the shift T gives an offset path
// through j, and the difference I(j) - I(i) is estimated from both ends of the pair with MIS
// weights that sum to one over the two directions (Lehtinen et al. 2013, sec. 4; Kettunen et al.
// 2015, sec. 4.2):
//     D_{i->j}(x) = w_{i->j}(x) [ f(T x) |T'(x)| - f(x) ] / p(x),
// w from the sampler's pdfs of base and offset (never from a chain's target, which would be
// circular). I(j) - I(i) = E_i[D_{i->j}] - E_j[D_{j->i}].
//
// "Very direct" light, an emitter or the environment seen directly from the camera, is never
// shifted (G-PT and G-BDPT do the same): its edges are sharp and its differences would put halos
// around every light. It is returned separately and added to the image after reconstruction.
#include <span>
#include <vector>

#include "core/image/neighbour_set.h"
#include "core/path/bidirectional.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"
#include "manifold/shift.h"

namespace gdmlt::mlt {

/// Paths are not Russian-rouletted (a shift needs the whole base path): an unbounded
/// max_depth becomes this many segments.
inline constexpr int kUnboundedDepthCap = 64;

struct GradientSample {
    /// The path tracer's estimate of the pixel (NEE and BSDF sampling, MIS) without very direct
    /// light.
    Rgb primal = Rgb::Zero();
    /// Emitters and environment seen directly from the camera.
    Rgb very_direct = Rgb::Zero();
};

/// The two halves of one link's difference D = offset - base: the base path's terms and the
/// offset path's (Jacobian included), per technique (BSDF sampling, NEE) each with its own
/// path's weight between the techniques, times the technique's weight between the two shift
/// directions (mlt/gradient_sample.cpp, sample_gradients). `base` is also pixel i's share of
/// its primal for this pair (the pair's weights for a path through i sum to one over "based in
/// i" and "shifted from j"), and `offset` is pixel j's share estimated from i: G-PT's "MIS
/// between pixels" primal, (1 / n_i) sum over i's n_i links of both (Kettunen et al. 2015).
struct LinkEstimate {
    Rgb base = Rgb::Zero();
    Rgb offset = Rgb::Zero();
    Rgb difference() const { return offset - base; }
};

/// Samples a base path through `film_position` (full-film raster coordinates) and, for every
/// link of its pixel, the MIS-weighted estimates towards the link's neighbour, written to
/// `estimates[k]` (same length as `links`).
GradientSample sample_gradients(const Scene& scene, const Vec2f& film_position,
                                SampleStream& stream, const PathSamplerSettings& path,
                                manifold::ShiftKind shift, std::span<const NeighbourLink> links,
                                std::span<LinkEstimate> estimates, PathCounters& counters,
                                manifold::ShiftCounters& shift_counters);

/// Bidirectional gradients (G-BDPT, Manzi et al. 2015, re-derived for primary sample space).
/// A base sample is a camera subpath (recorded as a unidirectional Path, with its next-event
/// samples) and a light subpath; strategy (s, t) connects their prefixes (core/path/
/// bidirectional.h). The shift keeps every light-subpath number, so the light subpath is the
/// same for base and offset, and shifts the camera subpath as the unidirectional shift does
/// (manifold/shift.h); strategy (s, t)'s offset path is the shifted camera prefix connected to
/// the same light prefix (for s = 1, the same point on the light). Per strategy the shift is a
/// bijection between the two pixels' paths of that strategy, so
///     I_st(j) - I_st(i) = E_x[ (w_st(y) f(y) |T'| - w_st(x) f(x)) / p_st(x) ],  y = T_st(x),
/// with the strategy weights w_st of each path its own (the MIS weights over strategies of the
/// offset path, from its own densities). Between the two directions of a shift the weight is
/// the power heuristic of p_st(x) and p_st(y) |T'|, the camera subpath's densities (the light
/// side is shared); a pair whose one side contributes nothing is estimated from the other side
/// alone (weight 1 there, 0 here), which both sides decide the same way.
///
/// Light tracing (t = 1) lands on another pixel than the camera sample's. With a neighbour set
/// and a light subpath that starts on an area light, it is shifted too: the path written in
/// camera order (vertex 0 the one the pinhole sees, the last on the light) is shifted as a
/// camera path is, to the neighbours of the pixel it lands on, by the maps that need no random
/// numbers (Path::replayable: reconnection, half vector, manifold walks; a vertex that would
/// need a replay fails the shift). In that measure (film position and directions in camera
/// order) the offset's value over the base's density is
///     f(y) |T'| / p(x) = C(x) f(y) |T'| / f(x),
/// C(x) = f(x) / p(x) the base's light tracing estimate, so no density of the light tracer in
/// camera order is needed; each path keeps its own MIS weight over strategies, and the weight
/// between the shift's directions is the power heuristic of the camera-order BSDF densities
/// times |T'| (any weights that sum to one over a pair are unbiased). Light paths from point,
/// spot, directional or environment lights, and paths without a neighbour set, are returned
/// as unshifted splats, added after reconstruction like very direct light (which, paths of one
/// segment, is left out here: GDMLT renders it in its own pass).
struct BidirectionalGradientSample {
    /// Strategies with t >= 2 at the camera sample's pixel, paths of >= 2 segments.
    Rgb primal = Rgb::Zero();
    /// Unshifted light tracing: per-light-path estimates at the film positions they land on.
    std::vector<BdptSample::Splat> light_splats;
    /// Shifted light tracing: per term, the pixel (crop index) it lands on, its estimate (per
    /// light path, as a splat), and its link estimates light_estimates[first .. first + count)
    /// for that pixel's links, in NeighbourSet::links order.
    struct LightTerm {
        std::uint32_t pixel = 0;
        Rgb primal = Rgb::Zero();
        std::uint32_t first = 0, count = 0;
    };
    std::vector<LightTerm> light_terms;
    std::vector<LinkEstimate> light_estimates;
    /// Strategy values that were not finite (dropped).
    int nonfinite = 0;
};

/// Reused storage (no allocation per sample once warm).
struct BidirectionalGradientScratch {
    BdptScratch bdpt;  // its `light` holds the light subpath
    std::vector<BdptVertex> base_camera, offset_camera;
    struct Term {
        int s = 0, t = 0;
        Rgb value = Rgb::Zero();  // w_st(x) f(x) / p_st(x)
    };
    std::vector<Term> terms;
    Path light_path;  // a light tracing path in camera order
    std::vector<BdptVertex> offset_light;
};

/// Samples a bidirectional base through `film_position`. Numbers: the camera subpath reads the
/// unidirectional layout (kDimensionsPerBounce per vertex) in a block of max_depth vertices,
/// then the light subpath its BDPT layout; no Russian roulette (max_depth -1 is capped at
/// kUnboundedDepthCap). `estimates[k]` gets link k's halves. `neighbours` (over the crop
/// window) enables the shifts of light tracing; without it light tracing is unshifted.
/// `options` (BidirectionalGradientOptions) change the MIS weights and may leave light tracing
/// out.
struct BidirectionalGradientOptions {
    /// The factor c of light tracing's density in every MIS weight over the strategies
    /// (BdptConnectionInput::light_tracing_scale; 1 = plain MIS).
    float light_tracing_scale = 1.f;
    /// Light tracing (t = 1) is left out: its weighted share comes from elsewhere (a light
    /// tracing pass with the same weights, render_ptracer with PtracerWeights::bdpt_mis).
    bool without_light_tracing = false;
};
void sample_bidirectional_gradients(const Scene& scene, const Vec2f& film_position,
                                    SampleStream& stream, const PathSamplerSettings& path,
                                    manifold::ShiftKind shift, std::span<const NeighbourLink> links,
                                    std::span<LinkEstimate> estimates,
                                    const NeighbourSet* neighbours,
                                    BidirectionalGradientScratch& scratch,
                                    BidirectionalGradientSample& out, PathCounters& counters,
                                    manifold::ShiftCounters& shift_counters,
                                    const BidirectionalGradientOptions& options = {});

}  // namespace gdmlt::mlt
