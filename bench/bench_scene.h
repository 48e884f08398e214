// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The scene a scene-level micro-benchmark runs on: the Mitsuba XML file named by the environment
// variable GDMLT_BENCH_SCENE (default: `fallback`, relative to the source tree), with the
// comma-separated name=value parameters of GDMLT_BENCH_DEFINES applied as the CLI's -D does
// (e.g. "res=64,max_depth=8"). Google Benchmark owns the command line, hence the environment.
#include <cstdlib>
#include <map>
#include <string>

#include "core/scene/scene.h"
#include "core/scene/scene_desc.h"

#ifndef GDMLT_SOURCE_DIR
#define GDMLT_SOURCE_DIR "."
#endif

namespace gdmlt::bench {

inline std::string env_or(const char* name, const std::string& fallback) {
    const char* value = std::getenv(name);
    return value && *value ? std::string(value) : fallback;
}

/// "a=1,b=2" -> {a: 1, b: 2}; empty items are skipped; an item without '=' is an InputError.
inline std::map<std::string, std::string> parse_defines(const std::string& text) {
    std::map<std::string, std::string> defines;
    std::size_t begin = 0;
    while (begin <= text.size()) {
        std::size_t end = text.find(',', begin);
        if (end == std::string::npos) end = text.size();
        const std::string item = text.substr(begin, end - begin);
        if (!item.empty()) {
            const std::size_t eq = item.find('=');
            if (eq == std::string::npos || eq == 0)
                throw InputError("GDMLT_BENCH_DEFINES expects name=value, got '" + item + "'");
            defines[item.substr(0, eq)] = item.substr(eq + 1);
        }
        begin = end + 1;
    }
    return defines;
}

/// The scene of GDMLT_BENCH_SCENE / GDMLT_BENCH_DEFINES; `fallback` is a path below the
/// source directory, e.g. "scenes/cbox.xml". Throws InputError (or the loader's errors).
inline Scene load_bench_scene(const std::string& fallback) {
    const std::string path =
        env_or("GDMLT_BENCH_SCENE", std::string(GDMLT_SOURCE_DIR "/") + fallback);
    ParseOptions options;
    options.defines = parse_defines(env_or("GDMLT_BENCH_DEFINES", ""));
    return build_scene(parse_scene_file(path, options));
}

}  // namespace gdmlt::bench
