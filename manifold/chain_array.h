// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The container of per-chain-vertex data in the manifold solver (chain vertices, constraint
// blocks, Newton right-hand sides and solutions).
//
// Why not std::vector: a Newton step of a walk builds a constraint system and solves it, and a
// GDMLT proposal walks up to three times per manifold shift (polish, there, back), so heap
// vectors sized by the chain meant millions of malloc/free pairs per second: with the other
// per-shift vectors they were 10% of GDMLT's time on cbox_glass_sphere (perf, 1 thread).
// Chains are short (two refractions through a glass sphere, four through a glass slab and
// back), so Boost's small_vector keeps up to kChainInlineVertices elements inline and spills
// to the heap only for longer chains: the same interface, no allocation in the common case.
#include <boost/container/small_vector.hpp>
#include <cstddef>
#include <span>

namespace gdmlt::manifold {

inline constexpr std::size_t kChainInlineVertices = 4;

template <class T>
using ChainArray = boost::container::small_vector<T, kChainInlineVertices>;

// Size arrays of Eigen types with an explicit value (ChainArray(n, v), assign(n, v)): resize(n)
// value-initialises through a temporary that GCC 12 at -O2 reports as maybe-uninitialized
// inside Boost (a false positive, but the sanitizer build prints it).

/// A view of the elements (Boost's iterators are not std::contiguous_iterator, so std::span
/// does not convert from the container by itself).
template <class T>
std::span<const T> as_span(const ChainArray<T>& array) {
    return {array.data(), array.size()};
}

}  // namespace gdmlt::manifold
