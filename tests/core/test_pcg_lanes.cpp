// SPDX-License-Identifier: GPL-3.0-or-later
// PcgLanes against Pcg32: every stream's numbers, bit for bit, on every instruction set the
// kernel is built for that this processor has.
#include <gtest/gtest.h>

#include <bit>
#include <vector>

#include "core/sampling/pcg_lanes.h"

namespace gdmlt {
namespace {

std::vector<SimdIsa> available_isas() {
    std::vector<SimdIsa> isas{SimdIsa::Baseline};
    if (best_simd_isa() != SimdIsa::Baseline) isas.push_back(SimdIsa::Avx2);
    if (best_simd_isa() == SimdIsa::Avx512) isas.push_back(SimdIsa::Avx512);
    return isas;
}

TEST(PcgLanes, EveryStreamDrawsWhatItsPcg32Draws) {
    // 200 streams (not a multiple of any vector width) with states spread over the whole 64-bit
    // range, so that all rotations (the top 5 bits of the state) occur; three rounds of 7 and
    // one of 8 draws, and between rounds every third stream dropped by move() as the wavefront
    // drops finished paths.
    for (const SimdIsa isa : available_isas()) {
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

}  // namespace
}  // namespace gdmlt
