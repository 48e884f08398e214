// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/reconstruct.h"

namespace gdmlt::reconstruct {

ReconstructResult reconstruct(const ReconstructInput& input, const ReconstructConfig& config) {
    switch (config.method) {
        case Method::l2:
            return solve_l2(input, config);
        case Method::l1:
            return solve_l1(input, config);
        case Method::cv:
            return solve_cv(input, config);
    }
    return solve_l1(input, config);
}

}  // namespace gdmlt::reconstruct
