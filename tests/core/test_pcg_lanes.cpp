// SPDX-License-Identifier: GPL-3.0-or-later
// PcgLanes against Pcg32: every stream's numbers, bit for bit, on every instruction set the
// kernel is built for that this processor has.
#include <gtest/gtest.h>

#include <bit>
#include <vector>

#include "core/sampling/pcg_lanes.h"
#include "core/sampling/sample_stream.h"

namespace gdmlt {
namespace {

TEST(PcgLanes, EveryStreamDrawsWhatItsPcg32Draws) {
    // 200 streams (not a multiple of any vector width) with states spread over the whole 64-bit
    // range, so that all rotations (the top 5 bits of the state) occur; three rounds of 7 and
    // one of 8 draws, and between rounds every third stream dropped by move() as the wavefront
    // drops finished paths.
    for (const SimdIsa isa : available_simd_isas()) {
        SCOPED_TRACE(testing::Message() << "instruction set " << static_cast<int>(isa));
        std::vector<Pcg32> reference;
        PcgLanes lanes;
        for (std::uint64_t i = 0; i < 200; ++i) {
            reference.emplace_back(derive_stream(7, i), derive_stream(8, i));
            lanes.set(i, reference.back());
        }
        auto draws = std::make_unique<PcgLanes::Draws>();
        int compared = 0;
        for (const std::size_t round_draws : {7u, 7u, 7u, 8u}) {
            lanes.next_floats(reference.size(), round_draws, *draws, isa);
            for (std::size_t i = 0; i < reference.size(); ++i)
                for (std::size_t d = 0; d < round_draws; ++d) {
                    const float expected = reference[i].next_float();
                    ASSERT_EQ(std::bit_cast<std::uint32_t>((*draws)[d][i]),
                              std::bit_cast<std::uint32_t>(expected))
                        << "stream " << i << " draw " << d;
                    ++compared;
                }
            std::vector<Pcg32> kept;
            for (std::size_t i = 0; i < reference.size(); ++i)
                if (i % 3 != 1) {
                    lanes.move(i, kept.size());
                    kept.push_back(reference[i]);
                }
            reference = kept;
        }
        EXPECT_GT(compared, 3000);
        for (std::size_t i = 0; i < reference.size(); ++i) EXPECT_EQ(lanes.get(i), reference[i]);
    }
}

TEST(PcgLanes, SeededStreamsAreThoseOfIndependentStreams) {
    // seed_samples against IndependentStream(derive_stream(seed, a, b)), the stream
    // pixel_sample gives: 250 streams (not a multiple of any vector width), identifiers from
    // small pixel and sample indices to the whole 64-bit range (a Pcg32 stream, seed 3), three
    // seeds including 0 and ~0. The keys past `count` hold other values and must not matter.
    for (const SimdIsa isa : available_simd_isas()) {
        SCOPED_TRACE(testing::Message() << "instruction set " << static_cast<int>(isa));
        Pcg32 ids(3, 4);
        PcgLanes::Keys id_a{}, id_b{};
        for (std::size_t i = 0; i < id_a.size(); ++i) {
            const std::uint64_t wide = (std::uint64_t{ids.next_u32()} << 32) | ids.next_u32();
            id_a[i] = i % 2 == 0 ? i * 977 : wide;
            id_b[i] = i % 3 == 0 ? i % 64 : ~wide;
        }
        constexpr std::size_t kCount = 250;
        for (const std::uint64_t seed :
             {std::uint64_t{0}, std::uint64_t{12345}, ~std::uint64_t{0}}) {
            PcgLanes lanes;
            lanes.seed_samples(kCount, seed, id_a, id_b, isa);
            for (std::size_t i = 0; i < kCount; ++i)
                ASSERT_EQ(lanes.get(i),
                          IndependentStream(derive_stream(seed, id_a[i], id_b[i])).rng())
                    << "stream " << i << " seed " << seed;
        }
    }
}

}  // namespace
}  // namespace gdmlt
