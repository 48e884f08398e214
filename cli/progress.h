// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Progress on stderr: a redrawn bar on a terminal, periodic plain lines otherwise (logs, CI).
#include <cstdint>
#include <mutex>

namespace gdmlt {

class ProgressBar {
  public:
    ProgressBar(bool terminal, bool quiet) : terminal_(terminal), quiet_(quiet) {}
    /// fraction in [0,1]; called from a background thread.
    void update(double fraction, std::uint64_t samples, double elapsed_s);
    void finish(bool interrupted);

  private:
    bool terminal_, quiet_;
    double last_line_s_ = -1e9;
    bool drawn_ = false;
    std::mutex mutex_;
};

}  // namespace gdmlt
