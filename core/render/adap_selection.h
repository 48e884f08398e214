// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// ADAP: which pixels each pixel takes its gradients against, chosen from per-pixel features
// (Manzi, Rousselle, Kettunen, Lehtinen and Zwicker 2014, "Improved Sampling for Gradient-Domain
// Metropolis Light Transport", adaptive neighbour selection).
//
// Lattice neighbours across a texture or geometry edge give differences that are large and, in
// a Monte Carlo estimate, noisy; neighbours that are "close" in feature space give small
// differences, and the reconstruction can tell real edges from noise. For feature k (albedo,
// shading normal, relative depth, shape id) the similarity of pixels i and j is
//     w_k(i, j) = exp(-max(0, |phi_k(i) - phi_k(j)|^2 - tau_k(i, j)) / sigma_k^2)
// with tau_k the squared difference the features' own noise explains (the sum of the two
// pixels' variances of the mean, per channel) and sigma_k a bandwidth; w(i, j) = min_k w_k(i, j),
// the thresholded-exponential feature weight of feature-guided denoisers (Rousselle, Manzi and
// Zwicker 2013). Among the candidates in a square window around i, i keeps the K nearest of
// those similar enough (w >= min_similarity), topped up with the most similar others when fewer
// pass: in a flat region ADAP is the 4-neighbour lattice, and noise in the features (a few
// samples per pixel, more behind glass) does not reshuffle neighbours whose weights all lie
// near 1 (ranking by w alone chose distant pixels by noise there, 40% more edges).
//
// The graph is built once from a feature pass and frozen before sampling: which offsets a pixel
// uses never depends on the samples that estimate them, so the estimator stays unbiased.
// Edges are symmetrised (both ends shift to each other, so the MIS of Kettunen et al. 2015,
// sec. 4.2, holds per edge), and every pixel keeps at least one horizontal and one vertical unit
// link, so no region hangs off the primal alone.
#include <cstdint>

#include "core/image/neighbour_set.h"
#include "core/render/feature_pass.h"

namespace gdmlt {

struct AdapSettings {
    int neighbours = 4;     // K: the candidates each pixel keeps
    int window_radius = 2;  // candidates: offsets with max(|dx|, |dy|) <= radius, except 0
    // Bandwidths sigma_k, in the units of each feature's difference:
    float sigma_albedo = 0.1f;  // RGB albedo in [0, 1]
    float sigma_normal = 0.2f;  // unit vectors: |n_i - n_j| = 0.2 is about 11 degrees
    float sigma_depth = 0.05f;  // |d_i - d_j| / max(d_i, d_j): relative depth
    float sigma_shape = 0.5f;   // a different shape id is a difference of 1
    /// Candidates at least this similar count as "the same surface" and are taken nearest
    /// first; 1 ranks every candidate by similarity alone.
    float min_similarity = 0.5f;
    /// Union: an edge exists when either end chose it (algorithms digest sec. 3.3). Mutual:
    /// only when both did (fewer edges, cheaper samples; the unit-link rule keeps the graph
    /// connected).
    bool mutual = false;
};

/// Similarity w(i, j) in [0, 1] of two pixels (index y * width + x) of `features`.
float adap_similarity(const FeatureImages& features, const AdapSettings& settings, int i, int j);

/// The frozen neighbour graph. Edges are ordered by offset (dy, then dx) and then by their
/// `from` pixel, each oriented from the smaller pixel index to the larger, so that the order is
/// a function of the edge set alone (the EXR round trip of core/image/gradient_layers.h keeps
/// it). Throws std::invalid_argument for settings out of range or features of mixed sizes.
NeighbourSet select_adap_neighbours(const FeatureImages& features, const AdapSettings& settings);

}  // namespace gdmlt
