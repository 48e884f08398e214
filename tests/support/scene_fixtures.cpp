// SPDX-License-Identifier: GPL-3.0-or-later
#include "tests/support/scene_fixtures.h"

#include <cmath>

#include "core/scene/scene_desc.h"

namespace gdmlt::test {

Scene scene_from_xml(const std::string& body, const BuildOptions& options) {
    const std::string xml = "<scene version=\"3.0.0\">\n" + body + "\n</scene>\n";
    return build_scene(parse_scene_string(xml, "test.xml"), options);
}

std::string sensor_xml(int resolution, float fov_deg, const std::string& origin, int spp) {
    const std::string res = std::to_string(resolution);
    return "<sensor type=\"perspective\"><float name=\"fov\" value=\"" + std::to_string(fov_deg) +
           "\"/><transform name=\"to_world\"><lookat origin=\"" + origin +
           "\" target=\"0, 0, 0\" up=\"0, 1, 0\"/></transform>"
           "<sampler type=\"independent\"><integer name=\"sample_count\" value=\"" +
           std::to_string(spp) +
           "\"/></sampler><film type=\"hdrfilm\"><integer name=\"width\" value=\"" + res +
           "\"/><integer name=\"height\" value=\"" + res +
           "\"/><rfilter type=\"box\"/></film></sensor>";
}

PixelStatistics pixel_statistics(const std::vector<float>& rgb, int channel) {
    const std::size_t n = rgb.size() / 3;
    double sum = 0.0, sum2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double v = rgb[3 * i + static_cast<std::size_t>(channel)];
        sum += v;
        sum2 += v * v;
    }
    PixelStatistics s;
    s.mean = sum / static_cast<double>(n);
    const double variance = std::max(0.0, sum2 / static_cast<double>(n) - s.mean * s.mean);
    s.standard_error = std::sqrt(variance / static_cast<double>(n - 1));
    return s;
}

}  // namespace gdmlt::test
