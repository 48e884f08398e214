// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/reconstruct_config.h"

namespace gdmlt::reconstruct {

std::optional<Method> parse_method(const std::string& name) {
    if (name == "l2") return Method::l2;
    if (name == "l1") return Method::l1;
    if (name == "cv") return Method::cv;
    return std::nullopt;
}

std::string to_string(Method method) {
    switch (method) {
        case Method::l2:
            return "l2";
        case Method::l1:
            return "l1";
        case Method::cv:
            return "cv";
    }
    return "?";
}

}  // namespace gdmlt::reconstruct
