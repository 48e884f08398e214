// SPDX-License-Identifier: GPL-3.0-or-later
#include "cli/progress.h"

#include <cstdio>
#include <string>

namespace gdmlt {

namespace {
std::string format_seconds(double s) {
    char buffer[32];
    if (s < 60.0)
        std::snprintf(buffer, sizeof buffer, "%.1fs", s);
    else
        std::snprintf(buffer, sizeof buffer, "%dm%02ds", static_cast<int>(s) / 60,
                      static_cast<int>(s) % 60);
    return buffer;
}
}  // namespace

void ProgressBar::update(double fraction, std::uint64_t samples, double elapsed_s) {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    const double eta = fraction > 1e-6 ? elapsed_s * (1.0 - fraction) / fraction : 0.0;
    const double rate = elapsed_s > 0.0 ? static_cast<double>(samples) / elapsed_s : 0.0;
    if (terminal_) {
        constexpr int kWidth = 40;
        const int filled = static_cast<int>(fraction * kWidth);
        std::string bar(static_cast<std::size_t>(filled), '+');
        bar.resize(kWidth, ' ');
        std::fprintf(stderr, "\r[%s] %5.1f%% (%s elapsed, ETA %s, %.2f M samples/s)", bar.c_str(),
                     100.0 * fraction, format_seconds(elapsed_s).c_str(),
                     format_seconds(eta).c_str(), rate / 1e6);
        drawn_ = true;
    } else if (elapsed_s - last_line_s_ >= 10.0) {
        // A line every 10 s keeps logs readable.
        std::fprintf(stderr, "progress: %.1f%% elapsed %s ETA %s %.2f M samples/s\n",
                     100.0 * fraction, format_seconds(elapsed_s).c_str(),
                     format_seconds(eta).c_str(), rate / 1e6);
        last_line_s_ = elapsed_s;
    }
    std::fflush(stderr);
}

void ProgressBar::finish(bool interrupted) {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    if (drawn_) std::fprintf(stderr, "\n");
    if (interrupted) std::fprintf(stderr, "interrupted: writing what has accumulated\n");
}

}  // namespace gdmlt
