// SPDX-License-Identifier: GPL-3.0-or-later
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <string>

#include "core/scene/scene_desc.h"

namespace gdmlt {

// Readable FileLoc in assertion failures (found by ADL, so it lives in gdmlt; static so that it
// cannot clash with other test files).
[[maybe_unused]] static void PrintTo(const FileLoc& loc, std::ostream* os) {
    *os << loc.to_string();
}

namespace {

namespace fs = std::filesystem;

/// A fresh directory per test, removed afterwards.
class TempDir {
  public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        path_ = fs::temp_directory_path() /
                ("gdmlt_scene_xml_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(path_);
        fs::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ignored;
        fs::remove_all(path_, ignored);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    const fs::path& path() const { return path_; }

    fs::path write(const std::string& relative, const std::string& text) const {
        const fs::path file = path_ / relative;
        fs::create_directories(file.parent_path());
        std::ofstream(file) << text;
        return file;
    }

  private:
    fs::path path_;
};

/// The only object child of `parent` with the given tag.
const ObjectDesc& child_with_tag(const SceneDesc& scene, const ObjectDesc& parent,
                                 const std::string& tag) {
    const ObjectDesc* found = nullptr;
    for (const ChildRef& child : parent.children) {
        const ObjectDesc& candidate = scene.objects.at(static_cast<std::size_t>(child.object));
        if (candidate.tag == tag) {
            EXPECT_EQ(found, nullptr) << "more than one <" << tag << ">";
            found = &candidate;
        }
    }
    if (found == nullptr) throw std::runtime_error("no <" + tag + "> child");
    return *found;
}

const ObjectDesc& first_child(const SceneDesc& scene, const ObjectDesc& parent) {
    return scene.objects.at(static_cast<std::size_t>(parent.children.at(0).object));
}

template <typename T>
const T& property_value(const ObjectDesc& object, const std::string& name) {
    const Property* property = object.find(name);
    if (property == nullptr) throw std::runtime_error("no property " + name);
    return std::get<T>(property->value);
}

Mat4d transform_of(const std::string& transform_body) {
    const SceneDesc scene = parse_scene_string(
        "<scene version=\"3.0.0\"><shape type=\"sphere\"><transform name=\"to_world\">" +
            transform_body + "</transform></shape></scene>",
        "t.xml");
    return property_value<TransformValue>(first_child(scene, scene.root_object()), "to_world")
        .matrix;
}

Vec3d apply_to_point(const Mat4d& m, const Vec3d& p) {
    return (m * p.homogeneous()).head<3>();
}

/// Parses `xml` expecting an InputError; returns its message after checking that it starts
/// with "file:line:".
std::string input_error_message(const std::string& xml, const std::string& file, int line,
                                const ParseOptions& options = {}) {
    try {
        parse_scene_string(xml, file, options);
    } catch (const InputError& error) {
        const std::string message = error.what();
        EXPECT_EQ(message.rfind(file + ":" + std::to_string(line) + ":", 0), 0u)
            << "expected an error at " << file << ":" << line << ", got: " << message;
        return message;
    }
    ADD_FAILURE() << "no InputError for:\n" << xml;
    return {};
}

TEST(SceneXml, DeeplyNestedObjectsAreAnInputErrorNotAStackOverflow) {
    // 6000 nested shapes once overflowed the stack (exit 139). 256 levels are allowed; the
    // 257th object is reported at its own line.
    const auto nested = [](int levels) {
        std::string xml = "<scene version=\"3.0.0\">\n";
        for (int i = 0; i < levels; ++i) xml += "<shape type=\"sphere\">\n";
        for (int i = 0; i < levels; ++i) xml += "</shape>";
        return xml + "</scene>";
    };
    const std::string message = input_error_message(nested(6000), "deep.xml", 2 + 256);
    EXPECT_NE(message.find("nested"), std::string::npos) << message;
    EXPECT_NO_THROW(parse_scene_string(nested(256), "ok.xml", {}));
}

// --- Transforms ---------------------------------------------------------------------------

TEST(SceneXml, ComposesTransformsInMitsubaOrder) {
    // Applied in the written order: scale (1,0,0) -> (2,0,0); rotate 90 degrees about +z ->
    // (0,2,0); translate -> (1,2,3).
    const Mat4d m = transform_of(
        R"(<scale value="2"/><rotate value="0, 0, 1" angle="90"/><translate value="1, 0, 3"/>)");
    EXPECT_TRUE(apply_to_point(m, Vec3d(1, 0, 0)).isApprox(Vec3d(1, 2, 3), 1e-12))
        << apply_to_point(m, Vec3d(1, 0, 0)).transpose();
}

TEST(SceneXml, RotatesRightHandedAboutTheGivenAxis) {
    // +90 degrees about +x takes +y to +z.
    const Mat4d m = transform_of(R"(<rotate x="1" angle="90"/>)");
    EXPECT_TRUE(apply_to_point(m, Vec3d(0, 1, 0)).isApprox(Vec3d(0, 0, 1), 1e-12));
}

TEST(SceneXml, ANonUnitRotationAxisIsTakenAsWrittenInVersion3AndNormalisedIn06) {
    // Mitsuba 3 builds c I + (1 - c) a a^T + s [a]x from the axis as written (its hello.xml
    // rotates about (0, 1, 1)). Reference: Mitsuba 3.9.1's ScalarTransform4f().rotate([0, 1, 1],
    // 15), printed to 7 digits.
    const Mat4d m = transform_of(R"(<rotate x="0" y="1" z="1" angle="15"/>)");
    Eigen::Matrix3d mitsuba;
    mitsuba << 0.9659258, -0.25881904, 0.25881904, 0.25881904, 1.0, 0.03407419, -0.25881904,
        0.03407419, 1.0;
    const Eigen::Matrix3d linear3 = m.topLeftCorner<3, 3>();
    EXPECT_TRUE(linear3.isApprox(mitsuba, 1e-6)) << m;
    // Mitsuba 0.6 normalised it: a rotation.
    const SceneDesc legacy = parse_scene_string(
        R"(<scene version="0.6.0"><shape type="sphere"><transform name="toWorld">
           <rotate x="0" y="1" z="1" angle="15"/></transform></shape></scene>)",
        "t.xml");
    const Mat4d r =
        property_value<TransformValue>(first_child(legacy, legacy.root_object()), "to_world")
            .matrix;
    const Eigen::Matrix3d linear = r.topLeftCorner<3, 3>();
    const bool orthonormal = (linear.transpose() * linear).isIdentity(1e-12);
    EXPECT_TRUE(orthonormal) << linear;
    EXPECT_NEAR(linear.determinant(), 1.0, 1e-12);
}

TEST(SceneXml, ReadsMatrixValuesRowMajor) {
    const Mat4d m = transform_of(R"(<matrix value="1 0 0 7  0 1 0 8  0 0 1 9  0 0 0 1"/>)");
    EXPECT_TRUE(apply_to_point(m, Vec3d::Zero()).isApprox(Vec3d(7, 8, 9)));
    const Mat4d m3 = transform_of(R"(<matrix value="0 -1 0, 1 0 0, 0 0 1"/>)");
    EXPECT_TRUE(apply_to_point(m3, Vec3d(1, 0, 0)).isApprox(Vec3d(0, 1, 0)));
}

TEST(SceneXml, ScalesNonUniformlyWithDefaultsOfOne) {
    const Mat4d m = transform_of(R"(<scale x="2" z="3"/>)");
    EXPECT_TRUE(apply_to_point(m, Vec3d(1, 1, 1)).isApprox(Vec3d(2, 1, 3)));
}

TEST(SceneXml, LookatColumnsAreLeftUpDirectionAndOrigin) {
    const Mat4d m = transform_of(R"(<lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>)");
    // dir = -z; left = up x dir = -x; new up = dir x left = +y.
    EXPECT_TRUE(m.col(0).isApprox(Eigen::Vector4d(-1, 0, 0, 0))) << m;
    EXPECT_TRUE(m.col(1).isApprox(Eigen::Vector4d(0, 1, 0, 0))) << m;
    EXPECT_TRUE(m.col(2).isApprox(Eigen::Vector4d(0, 0, -1, 0))) << m;
    EXPECT_TRUE(m.col(3).isApprox(Eigen::Vector4d(0, 0, 5, 1))) << m;
}

TEST(SceneXml, RejectsLookatWithUpParallelToTheViewDirection) {
    const std::string message = input_error_message(R"(<scene version="3.0.0">
<sensor type="perspective">
  <transform name="to_world">
    <lookat origin="0, 0, 0" target="0, 5, 0" up="0, 1, 0"/>
  </transform>
</sensor>
</scene>)",
                                                    "cam.xml", 4);
    EXPECT_NE(message.find("lookat"), std::string::npos) << message;
}

// --- Parameters ---------------------------------------------------------------------------

constexpr const char* kParameterScene = R"(<scene version="3.0.0">
<default name="res" value="256"/>
<default name="resolution" value="1024"/>
<film type="hdrfilm">
  <integer name="width" value="$res"/>
  <integer name="height" value="$resolution"/>
  <string name="label" value="$res-x$resolution"/>
</film>
</scene>)";

TEST(SceneXml, SubstitutesDefaultsByWholeParameterName) {
    const SceneDesc scene = parse_scene_string(kParameterScene, "p.xml");
    const ObjectDesc& film = child_with_tag(scene, scene.root_object(), "film");
    EXPECT_EQ(property_value<std::int64_t>(film, "width"), 256);
    EXPECT_EQ(property_value<std::int64_t>(film, "height"), 1024);
    EXPECT_EQ(property_value<std::string>(film, "label"), "256-x1024");
}

TEST(SceneXml, CommandLineDefinesOverrideDefaults) {
    ParseOptions options;
    options.defines["res"] = "32";
    const SceneDesc scene = parse_scene_string(kParameterScene, "p.xml", options);
    const ObjectDesc& film = child_with_tag(scene, scene.root_object(), "film");
    EXPECT_EQ(property_value<std::int64_t>(film, "width"), 32);
    EXPECT_EQ(property_value<std::int64_t>(film, "height"), 1024);
}

TEST(SceneXml, UnknownParameterIsAnErrorNamingItAndItsLine) {
    // Only $resolution is defined: $res must not match its prefix.
    const std::string message = input_error_message(R"(<scene version="3.0.0">
<default name="resolution" value="1024"/>
<film type="hdrfilm">
  <integer name="width" value="$res"/>
</film>
</scene>)",
                                                    "param.xml", 4);
    EXPECT_NE(message.find("$res "), std::string::npos) << message;
}

// --- Objects, ids and refs ----------------------------------------------------------------

TEST(SceneXml, ReferencedObjectIsSharedNotCopied) {
    const SceneDesc scene = parse_scene_string(R"(<scene version="3.0.0">
<bsdf type="diffuse" id="white"/>
<shape type="sphere"><ref id="white"/></shape>
<shape type="rectangle"><ref name="bsdf" id="white"/></shape>
</scene>)",
                                               "refs.xml");
    ASSERT_EQ(scene.objects.size(), 4u);  // scene, bsdf, two shapes: no copy of the bsdf
    const ObjectDesc& root = scene.root_object();
    ASSERT_EQ(root.children.size(), 3u);
    const int bsdf = root.children[0].object;
    EXPECT_EQ(scene.objects[static_cast<std::size_t>(bsdf)].id, "white");
    const ObjectDesc& sphere = scene.objects[static_cast<std::size_t>(root.children[1].object)];
    const ObjectDesc& rectangle = scene.objects[static_cast<std::size_t>(root.children[2].object)];
    ASSERT_EQ(sphere.children.size(), 1u);
    ASSERT_EQ(rectangle.children.size(), 1u);
    EXPECT_EQ(sphere.children[0].object, bsdf);
    EXPECT_EQ(rectangle.children[0].object, bsdf);
    EXPECT_EQ(rectangle.children[0].name, "bsdf");
    EXPECT_EQ(rectangle.children[0].loc, (FileLoc{"refs.xml", 4, 25}));
}

TEST(SceneXml, NestedObjectsBecomeNamedChildrenWithTheirLocation) {
    const SceneDesc scene = parse_scene_string(R"(<scene version="3.0.0">
<bsdf type="diffuse">
    <texture type="bitmap" name="reflectance">
        <string name="filename" value="tex/wood.png"/>
    </texture>
</bsdf>
</scene>)",
                                               "/scenes/room/nested.xml");
    const ObjectDesc& bsdf = child_with_tag(scene, scene.root_object(), "bsdf");
    EXPECT_EQ(bsdf.loc, (FileLoc{"/scenes/room/nested.xml", 2, 1}));
    ASSERT_EQ(bsdf.children.size(), 1u);
    EXPECT_EQ(bsdf.children[0].name, "reflectance");
    EXPECT_EQ(bsdf.children[0].loc, (FileLoc{"/scenes/room/nested.xml", 3, 5}));
    const ObjectDesc& texture = first_child(scene, bsdf);
    EXPECT_EQ(texture.type, "bitmap");
    // Relative file names are resolved against the scene file's directory.
    EXPECT_EQ(property_value<std::string>(texture, "filename"), "/scenes/room/tex/wood.png");
    EXPECT_EQ(texture.find("filename")->loc.line, 4);
}

TEST(SceneXml, AliasNamesTheSameObject) {
    const SceneDesc scene = parse_scene_string(R"(<scene version="3.0.0">
<bsdf type="diffuse" id="a"/>
<alias id="a" as="b"/>
<shape type="sphere"><ref id="b"/></shape>
</scene>)",
                                               "alias.xml");
    EXPECT_EQ(scene.objects.size(), 3u);
    const ObjectDesc& shape = child_with_tag(scene, scene.root_object(), "shape");
    EXPECT_EQ(scene.objects[static_cast<std::size_t>(shape.children.at(0).object)].id, "a");
}

// --- Typed values -------------------------------------------------------------------------

TEST(SceneXml, ConvertsPropertyTextToTypedValues) {
    const SceneDesc scene = parse_scene_string(R"(<scene version="3.0.0">
<bsdf type="test">
  <integer name="i" value="-42"/>
  <float name="f" value="+2.5e-1"/>
  <boolean name="b" value="true"/>
  <string name="s" value="hello world"/>
  <rgb name="c3" value="0.1 0.2,0.3"/>
  <rgb name="c1" value="0.5"/>
  <rgb name="hex" value="#ff8000"/>
  <spectrum name="sp" value="400:0.1, 700:0.9"/>
  <vector name="v1" value="2"/>
  <point name="p" value="1, 2, 3"/>
</bsdf>
</scene>)",
                                               "typed.xml");
    const ObjectDesc& bsdf = child_with_tag(scene, scene.root_object(), "bsdf");
    EXPECT_EQ(property_value<std::int64_t>(bsdf, "i"), -42);
    EXPECT_EQ(property_value<double>(bsdf, "f"), 0.25);
    EXPECT_TRUE(property_value<bool>(bsdf, "b"));
    EXPECT_EQ(property_value<std::string>(bsdf, "s"), "hello world");
    EXPECT_EQ(property_value<RgbValue>(bsdf, "c3"), (RgbValue{Vec3d(0.1, 0.2, 0.3), false}));
    EXPECT_EQ(property_value<RgbValue>(bsdf, "c1"), (RgbValue{Vec3d::Constant(0.5), false}));
    const RgbValue hex = property_value<RgbValue>(bsdf, "hex");
    EXPECT_TRUE(hex.srgb);
    EXPECT_TRUE(hex.value.isApprox(Vec3d(1.0, 128.0 / 255.0, 0.0)));
    EXPECT_EQ(property_value<SpectrumValue>(bsdf, "sp").text, "400:0.1, 700:0.9");
    EXPECT_EQ(property_value<Vec3Value>(bsdf, "v1").value, Vec3d(2, 2, 2));
    EXPECT_EQ(property_value<Vec3Value>(bsdf, "p").value, Vec3d(1, 2, 3));
}

TEST(SceneXml, ConvertsMitsuba06SpellingsToSnakeCase) {
    const SceneDesc scene = parse_scene_string(R"(<scene version="0.6.0">
<integrator type="path"><integer name="maxDepth" value="8"/></integrator>
<shape type="obj">
  <transform name="toWorld"><translate x="1" y="2"/></transform>
  <bsdf type="dielectric">
    <float name="intIOR" value="1.5"/>
    <srgb name="specularReflectance" value="0.5, 0.5, 0.5"/>
  </bsdf>
</shape>
<emitter type="point"><point name="position" x="1" z="3"/></emitter>
</scene>)",
                                               "old.xml");
    EXPECT_EQ(scene.version, "0.6.0");
    const ObjectDesc& root = scene.root_object();
    EXPECT_EQ(property_value<std::int64_t>(child_with_tag(scene, root, "integrator"), "max_depth"),
              8);
    const ObjectDesc& shape = child_with_tag(scene, root, "shape");
    const Mat4d& to_world = property_value<TransformValue>(shape, "to_world").matrix;
    EXPECT_TRUE(apply_to_point(to_world, Vec3d::Zero()).isApprox(Vec3d(1, 2, 0)));
    const ObjectDesc& bsdf = child_with_tag(scene, shape, "bsdf");
    EXPECT_EQ(property_value<double>(bsdf, "int_ior"), 1.5);
    EXPECT_EQ(property_value<RgbValue>(bsdf, "specular_reflectance"),
              (RgbValue{Vec3d::Constant(0.5), true}));
    EXPECT_EQ(property_value<Vec3Value>(child_with_tag(scene, root, "emitter"), "position").value,
              Vec3d(1, 0, 3));
}

TEST(SceneXml, KeepsVersion3NamesAsWritten) {
    const SceneDesc scene = parse_scene_string(
        R"(<scene version="3.0.0"><integrator type="path"><integer name="maxDepth" value="8"/></integrator></scene>)",
        "new.xml");
    const ObjectDesc& integrator = child_with_tag(scene, scene.root_object(), "integrator");
    EXPECT_NE(integrator.find("maxDepth"), nullptr);
    EXPECT_EQ(integrator.find("max_depth"), nullptr);
}

// --- Includes -----------------------------------------------------------------------------

TEST(SceneXml, InlinesIncludedFilesRelativeToTheIncludingFile) {
    const TempDir dir;
    dir.write("parts/bunny.xml", R"(<scene version="3.0.0">
    <shape type="obj" id="bunny">
        <string name="filename" value="meshes/bunny.obj"/>
    </shape>
</scene>)");
    const fs::path main = dir.write("main.xml", R"(<scene version="3.0.0">
    <include filename="parts/bunny.xml"/>
</scene>)");
    const SceneDesc scene = parse_scene_file(main.string());
    EXPECT_EQ(scene.scene_file, main.string());
    const ObjectDesc& shape = child_with_tag(scene, scene.root_object(), "shape");
    EXPECT_EQ(shape.id, "bunny");
    EXPECT_EQ(fs::path(shape.loc.file), dir.path() / "parts/bunny.xml");
    EXPECT_EQ(shape.loc.line, 2);
    EXPECT_EQ(fs::path(property_value<std::string>(shape, "filename")),
              dir.path() / "parts/meshes/bunny.obj");
}

TEST(SceneXml, PathTagsAreSearchedForFilesAndIncludesLatestFirst) {
    // Mitsuba 3's <path value="..."/> (96 of the scenes in its data repository use it): files
    // named by relative paths are looked for in the <path> directories, the latest first, and
    // then beside the file that names them. A <path> written after the property counts too:
    // Mitsuba's plugins resolve their files once the whole scene has been read.
    const TempDir dir;
    dir.write("textures/wood.png", "not read here");
    dir.write("fragments/wood.png", "not read here");
    dir.write("scenes/wood.png", "not read here");
    dir.write("meshes/bunny.obj", "not read here");
    dir.write("fragments/part.xml", R"(<scene version="3.0.0">
    <shape type="obj" id="bunny"><string name="filename" value="bunny.obj"/></shape>
</scene>)");
    const fs::path main = dir.write("scenes/main.xml", R"(<scene version="3.0.0">
    <path value="../textures"/>
    <path value="../fragments"/>
    <include filename="part.xml"/>
    <texture type="bitmap" id="found">
        <string name="filename" value="wood.png"/>
    </texture>
    <texture type="bitmap" id="missing">
        <string name="filename" value="nowhere.png"/>
    </texture>
    <path value="../meshes"/>
</scene>)");
    const SceneDesc scene = parse_scene_file(main.string());
    const ObjectDesc& root = scene.root_object();
    const ObjectDesc& shape = child_with_tag(scene, root, "shape");
    EXPECT_EQ(fs::path(property_value<std::string>(shape, "filename")),
              dir.path() / "meshes/bunny.obj");
    const ObjectDesc* found = nullptr;
    const ObjectDesc* missing = nullptr;
    for (const ChildRef& child : root.children) {
        const ObjectDesc& o = scene.objects[static_cast<std::size_t>(child.object)];
        if (o.id == "found") found = &o;
        if (o.id == "missing") missing = &o;
    }
    ASSERT_TRUE(found && missing);
    // In all three: the latest <path> wins, over the scene's own directory too.
    EXPECT_EQ(fs::path(property_value<std::string>(*found, "filename")),
              dir.path() / "fragments/wood.png");
    // Found nowhere: named beside the file that names it, for the reader's message.
    EXPECT_EQ(fs::path(property_value<std::string>(*missing, "filename")),
              dir.path() / "scenes/nowhere.png");
}

TEST(SceneXml, AnIncludeIsFoundBesideTheFilesThatIncludeItsIncluder) {
    // Mitsuba 3's participating_media scenes: scene.xml includes "include/base.xml", which
    // includes "include/preamble.xml", meant from the scene's directory (Mitsuba's resolver
    // keeps the outer files' directories after the including file's own).
    const TempDir dir;
    dir.write("include/preamble.xml", R"(<scene version="3.0.0"><default name="spp" value="3"/>
    <integrator type="path" id="found"/></scene>)");
    dir.write("include/base.xml", R"(<scene version="3.0.0">
    <include filename="include/preamble.xml"/></scene>)");
    const fs::path main = dir.write("scene.xml", R"(<scene version="3.0.0">
    <include filename="include/base.xml"/></scene>)");
    const SceneDesc scene = parse_scene_file(main.string());
    EXPECT_EQ(child_with_tag(scene, scene.root_object(), "integrator").id, "found");
    // Beside the including file wins.
    dir.write("include/include/preamble.xml", R"(<scene version="3.0.0">
    <integrator type="path" id="nearer"/></scene>)");
    const SceneDesc nearer = parse_scene_file(main.string());
    EXPECT_EQ(child_with_tag(nearer, nearer.root_object(), "integrator").id, "nearer");
}

TEST(SceneXml, AFileNamedInAnIncludeIsLookedForInTheScenesDirectoryFirst) {
    // Mitsuba's cbox-rgb.xml names meshes/... from fragments/shapes.xml, meaning the scene's
    // meshes/ folder; a file only beside the include is still found there.
    const TempDir dir;
    dir.write("meshes/floor.obj", "not read here");
    dir.write("fragments/meshes/floor.obj", "not read here");
    dir.write("fragments/meshes/wall.obj", "not read here");
    dir.write("fragments/shapes.xml", R"(<scene version="3.0.0">
    <shape type="obj" id="floor"><string name="filename" value="meshes/floor.obj"/></shape>
    <shape type="obj" id="wall"><string name="filename" value="meshes/wall.obj"/></shape>
</scene>)");
    const fs::path main = dir.write("scene.xml", R"(<scene version="3.0.0">
    <include filename="fragments/shapes.xml"/>
</scene>)");
    const SceneDesc scene = parse_scene_file(main.string());
    std::map<std::string, fs::path> files;
    for (const ChildRef& child : scene.root_object().children) {
        const ObjectDesc& o = scene.objects[static_cast<std::size_t>(child.object)];
        files[o.id] = property_value<std::string>(o, "filename");
    }
    EXPECT_EQ(files["floor"], dir.path() / "meshes/floor.obj");
    EXPECT_EQ(files["wall"], dir.path() / "fragments/meshes/wall.obj");
}

TEST(SceneXml, APathTagMustNameAFolderAndSitInTheScene) {
    const TempDir dir;
    const fs::path main = dir.write(
        "main.xml", "<scene version=\"3.0.0\">\n\n  <path value=\"no_such_folder\"/>\n</scene>\n");
    try {
        parse_scene_file(main.string());
        FAIL() << "no InputError";
    } catch (const InputError& error) {
        const std::string message = error.what();
        EXPECT_EQ(message.rfind(main.string() + ":3:", 0), 0u) << message;
        EXPECT_NE(message.find("no_such_folder"), std::string::npos) << message;
    }
    const std::string nested = input_error_message(
        "<scene version=\"3.0.0\">\n<shape type=\"obj\">\n<path value=\".\"/>\n</shape>\n"
        "</scene>",
        "nested.xml", 3);
    EXPECT_NE(nested.find("<path>"), std::string::npos) << nested;
}

TEST(SceneXml, ErrorInIncludedFileNamesThatFileAndLine) {
    const TempDir dir;
    dir.write("part.xml", "<scene version=\"3.0.0\">\n\n<shap type=\"obj\"/>\n</scene>\n");
    const fs::path main = dir.write(
        "main.xml", "<scene version=\"3.0.0\">\n<include filename=\"part.xml\"/>\n</scene>\n");
    try {
        parse_scene_file(main.string());
        FAIL() << "no InputError";
    } catch (const InputError& error) {
        EXPECT_EQ(std::string(error.what()).rfind((dir.path() / "part.xml").string() + ":3:1:", 0),
                  0u)
            << error.what();
    }
}

TEST(SceneXml, IncludeCycleIsAnErrorAtTheInclude) {
    const TempDir dir;
    dir.write("a.xml", "<scene version=\"3.0.0\">\n<include filename=\"b.xml\"/>\n</scene>\n");
    dir.write("b.xml", "<scene version=\"3.0.0\">\n\n<include filename=\"a.xml\"/>\n</scene>\n");
    try {
        parse_scene_file((dir.path() / "a.xml").string());
        FAIL() << "no InputError";
    } catch (const InputError& error) {
        const std::string message = error.what();
        EXPECT_EQ(message.rfind((dir.path() / "b.xml").string() + ":3:", 0), 0u) << message;
        EXPECT_NE(message.find("cycle"), std::string::npos) << message;
    }
}

TEST(SceneXml, AnIncludeBombIsAnInputErrorNotAnHourOfParsing) {
    // No cycle, but four levels of 20 includes each expand into 160000 parses.
    TempDir dir;
    const std::string files = "abcde";
    for (std::size_t level = 0; level + 1 < files.size(); ++level) {
        std::string text = "<scene version=\"3.0.0\">\n";
        for (int i = 0; i < 20; ++i)
            text += "<include filename=\"" + std::string(1, files[level + 1]) + ".xml\"/>\n";
        dir.write(std::string(1, files[level]) + ".xml", text + "</scene>");
    }
    dir.write("e.xml", "<scene version=\"3.0.0\"><default name=\"x\" value=\"1\"/></scene>");
    try {
        parse_scene_file((dir.path() / "a.xml").string());
        FAIL() << "160000 includes were parsed";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("includes"), std::string::npos) << e.what();
    }
    // Twenty includes of twenty (400) are fine.
    dir.write("c.xml", "<scene version=\"3.0.0\"><default name=\"x\" value=\"1\"/></scene>");
    EXPECT_NO_THROW(parse_scene_file((dir.path() / "a.xml").string()));
}

TEST(SceneXml, MissingIncludeIsAnErrorAtTheInclude) {
    const std::string message = input_error_message(
        "<scene version=\"3.0.0\">\n\n  <include filename=\"nowhere/missing.xml\"/>\n</scene>",
        "inc.xml", 3);
    EXPECT_NE(message.find("missing.xml"), std::string::npos) << message;
}

TEST(SceneXml, MissingSceneFileIsAnInputError) {
    EXPECT_THROW(parse_scene_file("/nonexistent/gdmlt/scene.xml"), InputError);
}

TEST(SceneXml, AFifoOrADeviceIsAnInputErrorNotAHang) {
    // Reading a FIFO blocks until a writer opens it, and /dev/zero never ends: before the
    // check, both hung the loader (a scene file, or an include).
    TempDir dir;
    const fs::path fifo = dir.path() / "scene.xml";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    try {
        parse_scene_file(fifo.string());
        FAIL() << "a FIFO was read as a scene";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
    }
    for (const std::string& included : {fifo.string(), std::string("/dev/zero")}) {
        const fs::path main =
            dir.write("main.xml", "<scene version=\"3.0.0\">\n  <include filename=\"" + included +
                                      "\"/>\n</scene>");
        try {
            parse_scene_file(main.string());
            FAIL() << included << " was included";
        } catch (const InputError& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find("not a regular file"), std::string::npos) << message;
            EXPECT_NE(message.find("main.xml:2"), std::string::npos) << message;
        }
    }
}

// --- Malformed input: file and line in every message --------------------------------------

TEST(SceneXml, TruncatedXmlReportsFileAndLine) {
    const std::string message = input_error_message(R"(<scene version="3.0.0">
<shape type="sphere">
    <float name="radius" value="1")",
                                                    "cut.xml", 3);
    EXPECT_NE(message.find("malformed XML"), std::string::npos) << message;
}

TEST(SceneXml, UnknownTagReportsFileLineAndColumn) {
    const std::string message = input_error_message(R"(<scene version="3.0.0">

    <shap type="sphere"/>
</scene>)",
                                                    "tag.xml", 3);
    EXPECT_EQ(message, "tag.xml:3:5: error: unknown tag <shap>");
}

TEST(SceneXml, BadFloatReportsFileAndLine) {
    const std::string message = input_error_message(R"(<scene version="3.0.0">
<shape type="sphere">
    <float name="radius" value="1.0x"/>
</shape>
</scene>)",
                                                    "num.xml", 3);
    EXPECT_NE(message.find("1.0x"), std::string::npos) << message;
}

TEST(SceneXml, BadIntegerAndBooleanReportFileAndLine) {
    input_error_message(
        "<scene version=\"3.0.0\">\n<sampler type=\"independent\">\n"
        "<integer name=\"sample_count\" value=\"1.5\"/></sampler></scene>",
        "int.xml", 3);
    input_error_message(
        "<scene version=\"3.0.0\">\n<integrator type=\"path\">\n\n"
        "<boolean name=\"hide_emitters\" value=\"yes please\"/></integrator></scene>",
        "bool.xml", 4);
}

TEST(SceneXml, UnknownRefIdReportsFileAndLine) {
    const std::string message = input_error_message(R"(<scene version="3.0.0">
<shape type="sphere">
    <ref id="whte"/>
</shape>
</scene>)",
                                                    "ref.xml", 3);
    EXPECT_NE(message.find("whte"), std::string::npos) << message;
}

TEST(SceneXml, ARefMayNameAnObjectDefinedLaterOrInALaterInclude) {
    // Mitsuba 3 resolves ids once the scene is read: its cbox-rgb.xml includes the shapes,
    // which refer to the light defined after the include.
    const TempDir dir;
    dir.write("shapes.xml", R"(<scene version="3.0.0">
    <shape type="sphere"><ref id="light"/><ref name="bsdf" id="white"/></shape>
</scene>)");
    dir.write("bsdfs.xml", R"(<scene version="3.0.0"><bsdf type="diffuse" id="white"/></scene>)");
    const fs::path main = dir.write("main.xml", R"(<scene version="3.0.0">
    <include filename="shapes.xml"/>
    <include filename="bsdfs.xml"/>
    <emitter type="area" id="light"/>
</scene>)");
    const SceneDesc scene = parse_scene_file(main.string());
    const ObjectDesc& shape = child_with_tag(scene, scene.root_object(), "shape");
    ASSERT_EQ(shape.children.size(), 2u);
    const ObjectDesc& light = scene.objects[static_cast<std::size_t>(shape.children[0].object)];
    const ObjectDesc& bsdf = scene.objects[static_cast<std::size_t>(shape.children[1].object)];
    EXPECT_EQ(light.id, "light");
    EXPECT_EQ(light.tag, "emitter");
    EXPECT_EQ(bsdf.id, "white");
    EXPECT_EQ(shape.children[1].name, "bsdf");
    EXPECT_EQ(shape.children[0].loc, (FileLoc{(dir.path() / "shapes.xml").string(), 2, 26}));
}

TEST(SceneXml, ACycleOfRefsIsAnErrorAtTheRefThatClosesIt) {
    // Forward references make cycles possible; followed, they would recurse without end.
    const std::string message = input_error_message(R"(<scene version="3.0.0">
<texture type="checkerboard" id="a"><ref name="color0" id="b"/></texture>
<texture type="checkerboard" id="b">
    <ref name="color0" id="a"/>
</texture>
</scene>)",
                                                    "cycle.xml", 4);
    EXPECT_NE(message.find("contain itself"), std::string::npos) << message;
    input_error_message(R"(<scene version="3.0.0">
<bsdf type="twosided" id="self">
  <ref id="self"/>
</bsdf>
</scene>)",
                        "self.xml", 3);
}

TEST(SceneXml, DuplicateIdReportsTheSecondDefinition) {
    input_error_message(R"(<scene version="3.0.0">
<bsdf type="diffuse" id="x"/>
<bsdf type="diffuse" id="x"/>
</scene>)",
                        "dup.xml", 3);
}

TEST(SceneXml, RefDirectlyInsideSceneIsAnError) {
    input_error_message(R"(<scene version="3.0.0">
<bsdf type="diffuse" id="x"/>
<ref id="x"/>
</scene>)",
                        "topref.xml", 3);
}

TEST(SceneXml, PropertyNestedInPropertyIsAnError) {
    input_error_message(R"(<scene version="3.0.0">
<bsdf type="diffuse">
  <rgb name="reflectance" value="0.5">
    <float name="x" value="1"/>
  </rgb>
</bsdf>
</scene>)",
                        "nest.xml", 4);
}

TEST(SceneXml, MissingRequiredAttributeIsAnError) {
    input_error_message(
        "<scene version=\"3.0.0\">\n<bsdf type=\"diffuse\">\n"
        "<float value=\"1\"/></bsdf></scene>",
        "attr.xml", 3);
    input_error_message("<scene version=\"3.0.0\">\n\n<shape/></scene>", "type.xml", 3);
}

TEST(SceneXml, TransformOperationOutsideTransformIsAnError) {
    input_error_message(
        "<scene version=\"3.0.0\">\n<shape type=\"sphere\">\n<translate x=\"1\"/></shape></scene>",
        "op.xml", 3);
}

TEST(SceneXml, RootMustBeSceneWithVersion) {
    input_error_message("<shape type=\"sphere\"/>", "root.xml", 1);
    input_error_message("<scene>\n</scene>", "ver.xml", 1);
}

}  // namespace
}  // namespace gdmlt
