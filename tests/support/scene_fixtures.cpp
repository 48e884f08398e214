// SPDX-License-Identifier: GPL-3.0-or-later
#include "tests/support/scene_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/render/adap_selection.h"
#include "core/render/feature_pass.h"
#include "core/scene/scene_desc.h"

namespace gdmlt::test {

Scene scene_from_xml(const std::string& body, const BuildOptions& options) {
    const std::string xml = "<scene version=\"3.0.0\">\n" + body + "\n</scene>\n";
    return build_scene(parse_scene_string(xml, "test.xml"), options);
}

Scene repository_scene(const std::string& name) {
    return build_scene(
        parse_scene_file(std::string(GDMLT_SOURCE_DIR) + "/scenes/" + name + ".xml"));
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

std::string cornell_box_xml(int resolution, bool glass_sphere) {
    std::string xml = sensor_xml(resolution, 39.3f, "0, 0, 3.9") + R"(
        <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.725, 0.71, 0.68"/></bsdf>
        <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.63, 0.065, 0.05"/></bsdf>
        <bsdf type="diffuse" id="green"><rgb name="reflectance" value="0.14, 0.45, 0.091"/></bsdf>
        <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><translate z="-1"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="90"/><translate x="-1"/></transform><ref id="red"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="-90"/><translate x="1"/></transform><ref id="green"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="0.25, 0.2, 1"/><rotate x="1" angle="90"/><translate y="0.99"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
            <emitter type="area"><rgb name="radiance" value="17, 12, 4"/></emitter></shape>
        <shape type="cube"><transform name="to_world"><scale value="0.3, 0.6, 0.3"/><rotate y="1" angle="20"/><translate value="-0.35, -0.4, -0.3"/></transform><ref id="white"/></shape>)";
    if (glass_sphere)
        xml +=
            R"(<shape type="sphere"><point name="center" value="0.4, -0.62, 0.3"/><float name="radius" value="0.38"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>)";
    else
        xml +=
            R"(<shape type="cube"><transform name="to_world"><scale value="0.3"/><rotate y="1" angle="-18"/><translate value="0.35, -0.7, 0.3"/></transform><ref id="white"/></shape>)";
    return xml;
}

std::string sealed_light_box_xml(int resolution) {
    return sensor_xml(resolution, 39.3f, "0, 0, 3.9") + R"(
        <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.725, 0.71, 0.68"/></bsdf>
        <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.63, 0.065, 0.05"/></bsdf>
        <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><translate z="-1"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="90"/><translate x="-1"/></transform><ref id="red"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="-90"/><translate x="1"/></transform><ref id="white"/></shape>
        <shape type="sphere"><point name="center" value="0, 0.45, 0"/><float name="radius" value="0.06"/>
            <emitter type="area"><rgb name="radiance" value="60, 50, 40"/></emitter></shape>
        <shape type="sphere"><point name="center" value="0, 0.45, 0"/><float name="radius" value="0.25"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf></shape>
        <shape type="cube"><transform name="to_world"><scale value="0.3"/><rotate y="1" angle="-18"/><translate value="0.35, -0.7, 0.3"/></transform><ref id="white"/></shape>)";
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

IndependentRenders independent_renders(const std::function<RenderOutput(std::uint64_t)>& render,
                                       int runs) {
    IndependentRenders r;
    std::vector<double> means;
    for (int k = 0; k < runs; ++k) {
        const RenderOutput out = render(100 + static_cast<std::uint64_t>(k));
        EXPECT_EQ(out.stats.nonfinite_samples_dropped, 0u);
        means.push_back(mean_luminance(out.image));
        if (k == 0) r.average = Image(out.image.width, out.image.height, 3);
        for (std::size_t i = 0; i < out.image.pixels.size(); ++i)
            r.average.pixels[i] += out.image.pixels[i] / static_cast<float>(runs);
    }
    for (double m : means) r.mean += m / runs;
    double variance = 0.0;
    for (double m : means) variance += (m - r.mean) * (m - r.mean) / (runs - 1);
    r.standard_error = std::sqrt(variance / runs);
    return r;
}

RenderOutput render_unbounded(const Scene& scene, int spp, std::uint64_t seed) {
    RenderSettings settings;
    settings.spp = spp;
    settings.seed = seed;
    settings.path.max_depth = -1;
    settings.path.rr_depth = 5;
    return render_path(scene, settings);
}

void expect_image_mean(const Image& image, const Rgb& expected, double relative_model_error) {
    for (int c = 0; c < 3; ++c) {
        const PixelStatistics s = pixel_statistics(image.pixels, c);
        EXPECT_NEAR(s.mean, expected[c],
                    5.0 * s.standard_error + relative_model_error * expected[c])
            << "channel " << c << ", standard error " << s.standard_error;
        EXPECT_LT(s.standard_error, 0.02 * expected[c]) << "budget too small for a meaningful test";
    }
}

RenderOutput reference_render(const Scene& scene) {
    RenderSettings pt;
    pt.spp = 4096;
    pt.seed = 1;
    pt.path.max_depth = 8;
    return render_path(scene, pt);
}

NeighbourSet adap_graph(const Scene& scene) {
    FeatureSettings fs;
    fs.spp = 4;
    fs.seed = 5;
    return select_adap_neighbours(render_features(scene, fs), AdapSettings{});
}

double mean_luminance(const Image& image) {
    double sum = 0.0;
    for (std::size_t i = 0; i < image.pixel_count(); ++i)
        sum +=
            luminance(Rgb(image.pixels[3 * i], image.pixels[3 * i + 1], image.pixels[3 * i + 2]));
    return sum / static_cast<double>(image.pixel_count());
}

Image ramp_image(int w, int h, int channels, float offset) {
    Image img(w, h, channels);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < channels; ++c)
                img(x, y, c) = offset + 0.37f * static_cast<float>(x) -
                               1.3e-3f * static_cast<float>(y * y) + 17.25f * static_cast<float>(c);
    return img;
}

}  // namespace gdmlt::test
