// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/scene_desc.h"

#include <filesystem>

namespace gdmlt {

std::string FileLoc::to_string() const {
    // Degrade gracefully when only part of the location is known (e.g. a file that could not be
    // opened has no line), so that messages never show a meaningless ":0:0".
    std::string text = file;
    if (line > 0) {
        text += ':' + std::to_string(line);
        if (column > 0) text += ':' + std::to_string(column);
    }
    return text;
}

namespace {

std::string format_input_error(const FileLoc& loc, const std::string& what) {
    const std::string where = loc.to_string();
    if (where.empty()) return "error: " + what;
    return where + ": error: " + what;
}

}  // namespace

InputError::InputError(const FileLoc& loc, const std::string& what)
    : std::runtime_error(format_input_error(loc, what)) {}

std::string input_file_problem(const std::string& path) {
    std::error_code error;
    const std::filesystem::file_status status = std::filesystem::status(path, error);
    if (!std::filesystem::exists(status)) return "no such file";
    if (!std::filesystem::is_regular_file(status)) return "not a regular file";
    return {};
}

}  // namespace gdmlt
