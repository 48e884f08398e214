// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// PCG32 (O'Neill 2014, "PCG: A family of simple fast space-efficient statistically good
// algorithms for random number generation"): 64-bit LCG state, XSH-RR output. Streams are
// selected by the increment, so (seed, pixel) or (seed, chain) pairs give independent
// sequences without any global state.
#include <cstdint>

namespace gdmlt {

/// Mixes 64 bits into 64 well-distributed bits (the SplitMix64 finaliser, Steele et al. 2014).
/// PcgLanes' kernel repeats it on vectors (mix_bits_lanes, core/sampling/pcg_lanes_kernel.inc).
constexpr std::uint64_t mix_bits(std::uint64_t v) {
    v ^= v >> 30;
    v *= 0xbf58476d1ce4e5b9ULL;
    v ^= v >> 27;
    v *= 0x94d049bb133111ebULL;
    v ^= v >> 31;
    return v;
}

/// The constants derive_stream mixes into the seed and the first identifier (named, because
/// PcgLanes::seed_samples repeats derive_stream in SIMD lanes).
inline constexpr std::uint64_t kStreamSeedSalt = 0x9e3779b97f4a7c15ULL;
inline constexpr std::uint64_t kStreamIdSalt = 0x632be59bd9b4e019ULL;

/// A stream key from a global seed and one or two identifiers (pixel index, pass, chain id).
constexpr std::uint64_t derive_stream(std::uint64_t seed, std::uint64_t id_a,
                                      std::uint64_t id_b = 0) {
    return mix_bits(mix_bits(seed ^ kStreamSeedSalt) ^ mix_bits(id_a + kStreamIdSalt) ^
                    (mix_bits(id_b) << 1));
}

class Pcg32 {
  public:
    Pcg32() { seed(0x853c49e6748fea9bULL, 0xda3e39cb94b95bdbULL); }
    Pcg32(std::uint64_t initial_state, std::uint64_t stream_id) { seed(initial_state, stream_id); }

    void seed(std::uint64_t initial_state, std::uint64_t stream_id) {
        state_ = 0;
        increment_ = (stream_id << 1u) | 1u;
        next_u32();
        state_ += initial_state;
        next_u32();
    }

    std::uint32_t next_u32() {
        const std::uint64_t old = state_;
        state_ = old * kMultiplier + increment_;
        const auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
        const auto rot = static_cast<std::uint32_t>(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31u));
    }

    /// Uniform in [0, 1): 24 random mantissa bits, so 1.0f is never returned.
    float next_float() { return static_cast<float>(next_u32() >> 8) * 0x1p-24f; }
    /// Uniform in [0, 1) with 53 bits.
    double next_double() {
        const std::uint64_t hi = next_u32(), lo = next_u32();
        return static_cast<double>(((hi << 32) | lo) >> 11) * 0x1p-53;
    }

    bool operator==(const Pcg32&) const = default;
    /// The generator's state and increment, for PcgLanes (many streams advanced in SIMD lanes).
    std::uint64_t state() const { return state_; }
    std::uint64_t increment() const { return increment_; }
    static constexpr std::uint64_t multiplier() { return kMultiplier; }
    static Pcg32 from_state(std::uint64_t state, std::uint64_t increment) {
        Pcg32 rng;
        rng.state_ = state;
        rng.increment_ = increment;
        return rng;
    }

  private:
    static constexpr std::uint64_t kMultiplier = 0x5851f42d4c957f2dULL;
    std::uint64_t state_ = 0;
    std::uint64_t increment_ = 0;
};

}  // namespace gdmlt
