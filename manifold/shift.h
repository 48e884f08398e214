// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Shift mappings: a base camera path through one pixel -> an offset path through a
// neighbouring pixel, with the Jacobian of the map (Lehtinen et al. 2013, sec. 4; Kettunen et
// al. 2015, sec. 4 and the shift of their public G-PT: reconnect at the first pair of
// connectable vertices, copy the half vector / replay the random numbers before that).
//
// Measure: every Jacobian here is the determinant of d(offset directions)/d(base directions) in
// the product of solid angles at the vertices, with the film position translated by exactly
// one pixel (Jacobian 1).
#include <array>
#include <cstdint>
#include <vector>

#include "core/path/path.h"
#include "core/scene/scene.h"

namespace gdmlt::manifold {

/// Which family of shifts to use (`--shift`). Auto (and Reconnect) reconnect at the first pair
/// of connectable vertices and copy the half vector / replay the random numbers before it;
/// HalfVector and Replay never reconnect. Auto also uses the manifold shift at a connectable
/// vertex whose base successors form a delta chain ending at a connectable vertex or emitter
/// (Manzi et al. 2014, sec. 4): the light-side end stays fixed and the chain is walked so that
/// it connects the offset vertex to it with the base's half vectors. Reconnect replays through
/// such chains instead (the comparison "without the manifold shift"). At a delta vertex the
/// half-vector copy is the same map as replaying its lobe choice (mirror or refract the offset's
/// own incident direction); at a diffuse vertex replay maps the same random numbers to the same
/// local direction.
enum class ShiftKind { Auto, Reconnect, HalfVector, Replay };

enum class ShiftStatus : int {
    Ok = 0,
    Escaped,                  // the offset ray left the scene where the base did not
    Occluded,                 // the reconnection segment is blocked
    ClassificationChanged,    // an offset vertex has another roughness class than the base's
    LobeChanged,              // replaying the random numbers chose another lobe
    TotalInternalReflection,  // the base refracted, the offset cannot
    // Manifold shift failures, named after the WalkFailure of the walk (or chain build):
    ManifoldNotConverged,
    ManifoldDistanceIncreased,
    ManifoldOccluded,
    ManifoldLeftManifold,
    ManifoldTotalInternalReflection,
    ManifoldSingularMatrix,
    ManifoldDegenerateChain,
    ManifoldNotReversible,  // walking the offset chain back did not return the base's chain
    NotReplayable,          // a path without random numbers (Path::replayable) would need a replay
    Count
};
const char* to_string(ShiftStatus status);
const char* to_string(ShiftKind kind);

/// An offset path and how it relates to its base.
struct ShiftResult {
    Path offset;  // y_0 ..; after `reconnected_at` its vertices are the base's
    /// log of the Jacobian of the direction leaving offset vertex k, per vertex (0 for shared
    /// vertices beyond the reconnection); the camera direction's is 0 (film translation).
    std::vector<double> log_jacobian;
    /// Offset vertices 0 .. valid_vertices-1 are valid: contributions that end there are usable.
    int valid_vertices = 0;
    int reconnected_at = -1;  // index of the first shared vertex, or -1
    /// Manifold shift: index of the first walked chain vertex (the diffuse vertex before it
    /// moved with the pixel), or -1. reconnected_at is then the chain's light-side end.
    int manifold_chain_at = -1;
    ShiftStatus status = ShiftStatus::Ok;
};

struct ShiftCounters {
    std::array<std::uint64_t, static_cast<int>(ShiftStatus::Count)> by_status{};
    std::uint64_t shifts = 0, reconnections = 0, half_vector_steps = 0, replay_steps = 0;
    /// Manifold shifts: walks attempted (the reversibility walk back not counted), successful
    /// shifts, and projections of all walks (both directions).
    std::uint64_t manifold_walks = 0, manifold_shifts = 0, manifold_iterations = 0;
    ShiftCounters& operator+=(const ShiftCounters& o);
};

/// Shifts `base` to the pixel `film_offset` away (e.g. (1, 0)).
ShiftResult shift_path(const Scene& scene, const Path& base, const Vec2f& film_offset,
                       ShiftKind kind, ShiftCounters& counters);
/// The same into `result`, whose storage is reused (no allocation once it is large enough).
void shift_path(const Scene& scene, const Path& base, const Vec2f& film_offset, ShiftKind kind,
                ShiftCounters& counters, ShiftResult& result);

/// One estimator term of a path: an emitter hit at vertex `vertex`, an escape to the
/// environment after it, or a next-event connection from it. f and the two pdfs are in the
/// path's own measure; `log_jacobian` converts them to the base's (for a base path: 0).
struct Contribution {
    enum class Kind { EmitterHit, Escape, NextEvent };
    Kind kind = Kind::EmitterHit;
    int vertex = 0;
    Rgb f = Rgb::Zero();
    double pdf = 0.0;        // of the technique that produced it (BSDF sampling or NEE)
    double pdf_other = 0.0;  // of the other technique for the same path (MIS)
    double log_jacobian = 0.0;
};

/// Every contribution of a path, in vertex order. `valid_vertices` limits an offset path;
/// `log_jacobian` (per vertex, may be empty for a base path) is accumulated into each term.
std::vector<Contribution> path_contributions(const Scene& scene, const Path& path,
                                             const std::vector<double>& log_jacobian,
                                             int valid_vertices, bool hide_emitters);
/// The same into `out` (cleared first; its storage is reused).
void path_contributions(const Scene& scene, const Path& path,
                        const std::vector<double>& log_jacobian, int valid_vertices,
                        bool hide_emitters, std::vector<Contribution>& out);

}  // namespace gdmlt::manifold
