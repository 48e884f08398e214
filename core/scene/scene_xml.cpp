// SPDX-License-Identifier: GPL-3.0-or-later
// Mitsuba XML (0.6 and 3 spellings) -> SceneDesc, with pugixml.
//
// The parser is deliberately ignorant of plugins: it checks the XML structure, resolves
// parameters, includes and refs, composes transforms and converts attribute text to typed values.
// Everything it reports carries file:line:column, computed from pugixml's node offsets into the
// text of the file the node came from (each included file keeps its own text).
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <pugixml.hpp>
#include <sstream>
#include <string_view>
#include <system_error>

#include "core/scene/plugin_scope.h"
#include "core/scene/scene_desc.h"

namespace gdmlt {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Source text and locations

/// The text of one XML file, kept so that byte offsets can be turned into line:column.
class SourceText {
  public:
    SourceText(std::string path, std::string text)
        : path_(std::move(path)), text_(std::move(text)) {
        line_starts_.push_back(0);
        for (std::size_t i = 0; i < text_.size(); ++i)
            if (text_[i] == '\n') line_starts_.push_back(i + 1);
    }

    const std::string& path() const { return path_; }
    const std::string& text() const { return text_; }

    FileLoc loc_at_offset(std::ptrdiff_t offset) const {
        if (offset < 0) return FileLoc{path_, 0, 0};
        const std::size_t clamped = std::min(static_cast<std::size_t>(offset), text_.size());
        const auto next_line = std::upper_bound(line_starts_.begin(), line_starts_.end(), clamped);
        const std::size_t line_index =
            static_cast<std::size_t>(next_line - line_starts_.begin()) - 1;
        return FileLoc{path_, static_cast<int>(line_index + 1),
                       static_cast<int>(clamped - line_starts_[line_index] + 1)};
    }

    FileLoc loc_of(const pugi::xml_node& node) const {
        std::ptrdiff_t offset = node.offset_debug();
        // For elements pugixml points at the name, just after '<'; editors show the '<'.
        if (offset > 0 && node.type() == pugi::node_element) --offset;
        return loc_at_offset(offset);
    }

  private:
    std::string path_;
    std::string text_;
    std::vector<std::size_t> line_starts_;  // byte offset of the first character of each line
};

/// Per-file state while walking that file's elements.
struct FileContext {
    const SourceText* source = nullptr;
    fs::path directory;         // relative paths written in this file are relative to this
    bool legacy_names = false;  // version < 2: camelCase property names
};

// ---------------------------------------------------------------------------------------------
// Small text helpers

bool is_identifier_start(char c) {
    return std::isalpha(static_cast<unsigned char>(c)) != 0 || c == '_';
}
bool is_identifier_char(char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_';
}
bool is_separator(char c) {
    return c == ',' || std::isspace(static_cast<unsigned char>(c)) != 0;
}

std::string_view trim(std::string_view text) {
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front())) != 0)
        text.remove_prefix(1);
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back())) != 0)
        text.remove_suffix(1);
    return text;
}

bool is_blank(std::string_view text) {
    return trim(text).empty();
}

std::string in_quotes(std::string_view text) {
    return "'" + std::string(text) + "'";
}

/// 0.6 camelCase -> snake_case: '_' before an uppercase letter that follows a lowercase letter
/// or digit, then everything lowercased. Runs of capitals stay one word (intIOR -> int_ior).
std::string camel_to_snake(std::string_view name) {
    std::string snake;
    snake.reserve(name.size() + 4);
    for (std::size_t i = 0; i < name.size(); ++i) {
        const unsigned char c = static_cast<unsigned char>(name[i]);
        if (std::isupper(c) != 0 && i > 0) {
            const unsigned char previous = static_cast<unsigned char>(name[i - 1]);
            if (std::islower(previous) != 0 || std::isdigit(previous) != 0) snake += '_';
        }
        snake += static_cast<char>(std::tolower(c));
    }
    return snake;
}

/// Numbers separated by commas and/or whitespace.
std::vector<std::string_view> split_numbers(std::string_view text) {
    std::vector<std::string_view> tokens;
    std::size_t i = 0;
    while (i < text.size()) {
        while (i < text.size() && is_separator(text[i])) ++i;
        const std::size_t start = i;
        while (i < text.size() && !is_separator(text[i])) ++i;
        if (i > start) tokens.push_back(text.substr(start, i - start));
    }
    return tokens;
}

double parse_double(std::string_view token, const FileLoc& loc, std::string_view what) {
    std::string_view digits = trim(token);
    // from_chars rejects a leading '+', which people do write.
    if (digits.size() > 1 && digits.front() == '+' && digits[1] != '-') digits.remove_prefix(1);
    double value = 0.0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (digits.empty() || error != std::errc() || end != digits.data() + digits.size() ||
        std::isnan(value))
        throw InputError(loc, "bad number " + in_quotes(token) + " in " + std::string(what));
    return value;
}

std::int64_t parse_int64(std::string_view token, const FileLoc& loc, std::string_view what) {
    std::string_view digits = trim(token);
    if (digits.size() > 1 && digits.front() == '+' && digits[1] != '-') digits.remove_prefix(1);
    std::int64_t value = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (digits.empty() || error != std::errc() || end != digits.data() + digits.size())
        throw InputError(loc, "bad integer " + in_quotes(token) + " in " + std::string(what));
    return value;
}

bool parse_bool(std::string_view token, const FileLoc& loc, std::string_view what) {
    std::string lower(trim(token));
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower == "true") return true;
    if (lower == "false") return false;
    throw InputError(loc, "bad boolean " + in_quotes(token) + " in " + std::string(what) +
                              " (expected true or false)");
}

std::vector<double> parse_numbers(std::string_view text, const FileLoc& loc,
                                  std::string_view what) {
    std::vector<double> numbers;
    for (std::string_view token : split_numbers(text))
        numbers.push_back(parse_double(token, loc, what));
    return numbers;
}

Vec3d parse_three_numbers(std::string_view text, const FileLoc& loc, std::string_view what) {
    const std::vector<double> numbers = parse_numbers(text, loc, what);
    if (numbers.size() != 3)
        throw InputError(loc, "expected 3 numbers in " + std::string(what) + ", got " +
                                  std::to_string(numbers.size()) + " in " + in_quotes(text));
    return Vec3d(numbers[0], numbers[1], numbers[2]);
}

int hex_digit_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/// "#rrggbb" -> sRGB-encoded components in [0, 1].
Vec3d parse_hex_color(std::string_view text, const FileLoc& loc, std::string_view what) {
    if (text.size() != 7)
        throw InputError(loc, "bad colour " + in_quotes(text) + " in " + std::string(what) +
                                  " (expected #rrggbb)");
    Vec3d color;
    for (int channel = 0; channel < 3; ++channel) {
        const int high = hex_digit_value(text[static_cast<std::size_t>(1 + 2 * channel)]);
        const int low = hex_digit_value(text[static_cast<std::size_t>(2 + 2 * channel)]);
        if (high < 0 || low < 0)
            throw InputError(loc, "bad colour " + in_quotes(text) + " in " + std::string(what) +
                                      " (expected #rrggbb)");
        color[channel] = static_cast<double>(high * 16 + low) / 255.0;
    }
    return color;
}

/// Mitsuba's look-at frame: columns [left, up, dir, origin], so local +z looks at the target.
Mat4d look_at_matrix(const Vec3d& origin, const Vec3d& target, const std::optional<Vec3d>& up,
                     const FileLoc& loc) {
    const Vec3d offset = target - origin;
    if (!(offset.norm() > 0.0))
        throw InputError(loc, "degenerate <lookat>: origin and target coincide");
    const Vec3d dir = offset.normalized();
    Vec3d up_hint;
    if (up) {
        up_hint = *up;
    } else {
        // No up given: any vector not parallel to dir will do.
        up_hint = std::abs(dir.y()) < 0.9 ? Vec3d::UnitY() : Vec3d::UnitX();
    }
    const Vec3d unnormalized_left = up_hint.cross(dir);
    // Relative test: the sine of the angle between up and dir, scaled by |up|.
    if (!(unnormalized_left.norm() > 1e-9 * up_hint.norm()))
        throw InputError(loc, "degenerate <lookat>: up vector is parallel to the view direction");
    const Vec3d left = unnormalized_left.normalized();
    const Vec3d new_up = dir.cross(left);
    Mat4d m = Mat4d::Identity();
    m.block<3, 1>(0, 0) = left;
    m.block<3, 1>(0, 1) = new_up;
    m.block<3, 1>(0, 2) = dir;
    m.block<3, 1>(0, 3) = origin;
    return m;
}

bool is_object_tag(std::string_view tag) {
    static constexpr std::string_view kObjectTags[] = {"integrator", "sensor", "film", "sampler",
                                                       "rfilter",    "shape",  "bsdf", "emitter",
                                                       "texture",    "medium", "phase"};
    return std::find(std::begin(kObjectTags), std::end(kObjectTags), tag) != std::end(kObjectTags);
}

bool is_property_tag(std::string_view tag) {
    static constexpr std::string_view kPropertyTags[] = {
        "integer", "float",    "boolean", "string", "rgb",
        "srgb",    "spectrum", "point",   "vector", "transform"};
    return std::find(std::begin(kPropertyTags), std::end(kPropertyTags), tag) !=
           std::end(kPropertyTags);
}

bool is_transform_operation_tag(std::string_view tag) {
    return tag == "translate" || tag == "rotate" || tag == "scale" || tag == "matrix" ||
           tag == "lookat";
}

/// The file's contents, or nullopt and the reason in `why`. Regular files only
/// (input_file_problem).
std::optional<std::string> read_text_file(const fs::path& path, std::string& why) {
    why = input_file_problem(path.string());
    if (!why.empty()) return std::nullopt;
    std::ifstream stream(path, std::ios::binary);
    std::ostringstream contents;
    if (stream) contents << stream.rdbuf();
    if (!stream || stream.bad()) {
        why = "cannot read it";
        return std::nullopt;
    }
    return std::move(contents).str();
}

/// Identity of a file for include-cycle detection.
std::string file_identity(const fs::path& path) {
    std::error_code error;
    fs::path canonical = fs::weakly_canonical(path, error);
    if (error) canonical = fs::absolute(path, error).lexically_normal();
    return canonical.string();
}

// ---------------------------------------------------------------------------------------------
// The parser

class SceneParser {
  public:
    explicit SceneParser(const ParseOptions& options) : parameters_(options.defines) {}

    SceneDesc parse(std::string text, const std::string& path) {
        scene_.scene_file = path;
        const SourceText source(path, std::move(text));
        const pugi::xml_document document = load_document(source);
        const pugi::xml_node root = scene_root(document, source);
        const FileContext context = make_context(source, root, fs::path(path).parent_path());
        scene_.version = root.attribute("version").value();

        ObjectDesc root_object;
        root_object.tag = "scene";
        root_object.type = root.attribute("type").value();
        root_object.loc = source.loc_of(root);
        scene_.objects.push_back(std::move(root_object));
        scene_.root = 0;

        include_stack_.push_back(file_identity(path));
        parse_children(root, context, scene_.root);
        include_stack_.pop_back();
        resolve_refs();
        // Files named by properties are looked up once the whole scene is read, as Mitsuba 3's
        // plugins do after parsing: every <path>, also one written after the property, counts.
        for (const PendingFilename& f : pending_filenames_) {
            Property& property = object(f.object).properties.at(f.property);
            property.value = resolve_path(f.written, f.directory).string();
        }
        return std::move(scene_);
    }

  private:
    static pugi::xml_document load_document(const SourceText& source) {
        pugi::xml_document document;
        const pugi::xml_parse_result result = document.load_buffer(
            source.text().data(), source.text().size(), pugi::parse_default, pugi::encoding_utf8);
        if (!result)
            throw InputError(source.loc_at_offset(result.offset),
                             std::string("malformed XML: ") + result.description());
        return document;
    }

    static pugi::xml_node scene_root(const pugi::xml_document& document, const SourceText& source) {
        const pugi::xml_node root = document.document_element();
        if (std::string_view(root.name()) != "scene")
            throw InputError(source.loc_of(root), "the root element must be <scene>, not <" +
                                                      std::string(root.name()) + ">");
        return root;
    }

    /// Reads the root's version attribute to decide whether names need converting.
    FileContext make_context(const SourceText& source, const pugi::xml_node& root,
                             fs::path directory) const {
        const FileLoc loc = source.loc_of(root);
        const pugi::xml_attribute version_attribute = root.attribute("version");
        if (!version_attribute)
            throw InputError(loc, "<scene> needs a 'version' attribute (e.g. \"3.0.0\")");
        const std::string version = version_attribute.value();
        int major = 0;
        const char* begin = version.data();
        const char* end = version.data() + version.size();
        const auto [parsed_end, error] = std::from_chars(begin, end, major);
        if (error != std::errc() || (parsed_end != end && *parsed_end != '.'))
            throw InputError(loc, "bad scene version " + in_quotes(version));
        return FileContext{&source, std::move(directory), major < 2};
    }

    // --- attributes -----------------------------------------------------------------------

    /// `$name` -> value of the parameter. The name is the longest identifier after '$', so
    /// `$res` never matches a prefix of `$resolution`.
    std::string substitute(std::string_view text, const FileLoc& loc) const {
        std::string result;
        result.reserve(text.size());
        std::size_t i = 0;
        while (i < text.size()) {
            if (text[i] == '$' && i + 1 < text.size() && is_identifier_start(text[i + 1])) {
                std::size_t end = i + 2;
                while (end < text.size() && is_identifier_char(text[end])) ++end;
                const std::string name(text.substr(i + 1, end - i - 1));
                const auto found = parameters_.find(name);
                if (found == parameters_.end())
                    throw InputError(loc, "unknown parameter $" + name + " (define it with -D " +
                                              name + "=... or a <default>)");
                result += found->second;
                i = end;
            } else {
                result += text[i++];
            }
        }
        return result;
    }

    std::optional<std::string> attribute(const pugi::xml_node& node, const char* key,
                                         const FileLoc& loc) const {
        const pugi::xml_attribute found = node.attribute(key);
        if (!found) return std::nullopt;
        return substitute(found.value(), loc);
    }

    std::string required_attribute(const pugi::xml_node& node, const char* key,
                                   const FileLoc& loc) const {
        std::optional<std::string> value = attribute(node, key, loc);
        if (!value)
            throw InputError(loc, "<" + std::string(node.name()) + "> is missing the required '" +
                                      key + "' attribute");
        return std::move(*value);
    }

    std::string property_name(const pugi::xml_node& node, const FileContext& context,
                              const FileLoc& loc) const {
        const std::string name = required_attribute(node, "name", loc);
        return context.legacy_names ? camel_to_snake(name) : name;
    }

    // --- structure ------------------------------------------------------------------------

    void reject_text(const pugi::xml_node& node, const FileContext& context) const {
        if (node.type() != pugi::node_pcdata && node.type() != pugi::node_cdata) return;
        const std::string_view text = node.value();
        if (is_blank(text)) return;
        // Point at the first visible character, not at the whitespace before it.
        std::size_t leading = 0;
        while (std::isspace(static_cast<unsigned char>(text[leading])) != 0) ++leading;
        throw InputError(context.source->loc_at_offset(node.offset_debug() +
                                                       static_cast<std::ptrdiff_t>(leading)),
                         "unexpected text " + in_quotes(trim(text)) + " inside <" +
                             std::string(node.parent().name()) + ">");
    }

    void parse_children(const pugi::xml_node& element, const FileContext& context, int parent) {
        for (const pugi::xml_node& child : element.children()) {
            if (child.type() == pugi::node_element)
                parse_element(child, context, parent);
            else
                reject_text(child, context);
        }
    }

    ObjectDesc& object(int index) { return scene_.objects.at(static_cast<std::size_t>(index)); }

    void parse_element(const pugi::xml_node& element, const FileContext& context, int parent) {
        const std::string tag = element.name();
        const FileLoc loc = context.source->loc_of(element);
        if (is_object_tag(tag)) {
            std::string name = attribute(element, "name", loc).value_or("");
            if (context.legacy_names) name = camel_to_snake(name);
            const int child = parse_object(element, context);
            object(parent).children.push_back(ChildRef{std::move(name), child, loc});
        } else if (is_property_tag(tag)) {
            Property property = parse_property(element, context, loc);
            if (property.name == "filename")
                if (const auto* written = std::get_if<std::string>(&property.value))
                    pending_filenames_.push_back(PendingFilename{
                        parent, object(parent).properties.size(), *written, context.directory});
            object(parent).properties.push_back(std::move(property));
        } else if (tag == "ref") {
            parse_ref(element, context, loc, parent);
        } else if (tag == "default") {
            const std::string name = required_attribute(element, "name", loc);
            const std::string value = required_attribute(element, "value", loc);
            reject_children(element, context);
            // -D on the command line (already in parameters_) wins over the file's default.
            parameters_.try_emplace(name, value);
        } else if (tag == "include") {
            parse_include(element, context, loc, parent);
        } else if (tag == "path") {
            parse_search_path(element, context, loc, parent);
        } else if (tag == "alias") {
            const std::string id = required_attribute(element, "id", loc);
            const std::string alias = required_attribute(element, "as", loc);
            reject_children(element, context);
            register_id(alias, lookup_id(id, loc), loc);
        } else if (tag == "scene") {
            throw InputError(loc, "<scene> can only be the root element");
        } else if (is_transform_operation_tag(tag)) {
            throw InputError(loc, "<" + tag + "> is only allowed inside <transform>");
        } else if (const auto reason = out_of_scope_reason(tag, "")) {
            throw InputError(loc, out_of_scope_message(tag, "", *reason));
        } else {
            throw InputError(loc, "unknown tag <" + tag + ">");
        }
    }

    void reject_children(const pugi::xml_node& element, const FileContext& context,
                         bool allow_text = false) const {
        for (const pugi::xml_node& child : element.children()) {
            if (child.type() == pugi::node_element)
                throw InputError(context.source->loc_of(child),
                                 "<" + std::string(child.name()) + "> is not allowed inside <" +
                                     std::string(element.name()) + ">");
            if (!allow_text) reject_text(child, context);
        }
    }

    int parse_object(const pugi::xml_node& element, const FileContext& context) {
        const FileLoc loc = context.source->loc_of(element);
        // Objects nest through recursion here and in the scene builder: a bound keeps a
        // hostile file (a <shape> nested 6000 deep crashed with a stack overflow) an input
        // error. Real scenes nest a handful of levels (shape > bsdf > texture).
        if (object_depth_ >= kMaxObjectNesting)
            throw InputError(loc, "objects nested more than " + std::to_string(kMaxObjectNesting) +
                                      " levels deep");
        ++object_depth_;
        ObjectDesc desc;
        desc.tag = element.name();
        desc.type = required_attribute(element, "type", loc);
        desc.id = attribute(element, "id", loc).value_or("");
        desc.loc = loc;
        const int index = static_cast<int>(scene_.objects.size());
        scene_.objects.push_back(std::move(desc));
        parse_children(element, context, index);
        --object_depth_;
        // Registered after the children so that an object cannot reference itself or an
        // ancestor (which would make the object graph cyclic).
        if (!object(index).id.empty()) register_id(object(index).id, index, loc);
        return index;
    }

    void register_id(const std::string& id, int index, const FileLoc& loc) {
        const auto [existing, inserted] = ids_.try_emplace(id, index);
        if (!inserted)
            throw InputError(loc, "duplicate id " + in_quotes(id) + " (first used at " +
                                      object(existing->second).loc.to_string() + ")");
    }

    int lookup_id(const std::string& id, const FileLoc& loc) const {
        const auto found = ids_.find(id);
        if (found == ids_.end()) throw InputError(loc, "reference to unknown id " + in_quotes(id));
        return found->second;
    }

    void parse_ref(const pugi::xml_node& element, const FileContext& context, const FileLoc& loc,
                   int parent) {
        const std::string id = required_attribute(element, "id", loc);
        std::string name = attribute(element, "name", loc).value_or("");
        if (context.legacy_names) name = camel_to_snake(name);
        reject_children(element, context);
        if (parent == scene_.root)
            throw InputError(loc, "<ref id=" + in_quotes(id) +
                                      "> directly inside <scene> has no effect; put it inside "
                                      "the object that uses it");
        // Resolved once the scene is read: Mitsuba 3 lets a <ref> name an object defined later
        // in the file or in a later include (its cbox-rgb.xml refers to the light it defines
        // last).
        pending_refs_.push_back(PendingRef{parent, object(parent).children.size(), id});
        object(parent).children.push_back(ChildRef{std::move(name), -1, loc});
    }

    /// Points every <ref> at its object, then refuses a cycle of references (an object that
    /// contains itself), which forward references make possible, at the <ref> that closes it.
    void resolve_refs() {
        for (const PendingRef& ref : pending_refs_) {
            ChildRef& child = object(ref.object).children.at(ref.child);
            child.object = lookup_id(ref.id, child.loc);
        }
        // Iterative depth-first search (a chain of references may be long): 0 unvisited,
        // 1 on the current path, 2 done.
        std::vector<char> state(scene_.objects.size(), 0);
        std::vector<std::pair<int, std::size_t>> stack;  // object, next child to visit
        for (int start = 0; start < static_cast<int>(scene_.objects.size()); ++start) {
            if (state[static_cast<std::size_t>(start)] != 0) continue;
            state[static_cast<std::size_t>(start)] = 1;
            stack.emplace_back(start, 0);
            while (!stack.empty()) {
                auto& [current, next] = stack.back();
                const std::vector<ChildRef>& children = object(current).children;
                if (next == children.size()) {
                    state[static_cast<std::size_t>(current)] = 2;
                    stack.pop_back();
                    continue;
                }
                const ChildRef& child = children[next++];
                char& child_state = state[static_cast<std::size_t>(child.object)];
                if (child_state == 1)
                    throw InputError(child.loc, "this reference makes " +
                                                    describe_object(child.object) +
                                                    " contain itself");
                if (child_state == 0) {
                    child_state = 1;
                    stack.emplace_back(child.object, 0);
                }
            }
        }
    }

    std::string describe_object(int index) {
        const ObjectDesc& o = object(index);
        return "<" + o.tag + " type=" + in_quotes(o.type) +
               (o.id.empty() ? "" : " id=" + in_quotes(o.id)) + ">";
    }

    void parse_include(const pugi::xml_node& element, const FileContext& context,
                       const FileLoc& loc, int parent) {
        const std::string filename = required_attribute(element, "filename", loc);
        reject_children(element, context);
        const fs::path path = resolve_include(filename, context.directory);
        const std::string identity = file_identity(path);
        if (std::find(include_stack_.begin(), include_stack_.end(), identity) !=
            include_stack_.end()) {
            std::string chain;
            for (const std::string& file : include_stack_) chain += file + " -> ";
            throw InputError(loc, "include cycle: " + chain + identity);
        }
        // Without cycles, a file may still include another many times, and that one the next:
        // k levels of n includes expand into n^k parses (an "include bomb"). Real scenes
        // include a few dozen files.
        if (++includes_ > kMaxIncludes)
            throw InputError(loc, "more than " + std::to_string(kMaxIncludes) +
                                      " includes (each counted every time it is included)");
        std::string why;
        std::optional<std::string> text = read_text_file(path, why);
        if (!text)
            throw InputError(loc,
                             "cannot open included file " + in_quotes(path.string()) + ": " + why);

        const SourceText source(path.string(), std::move(*text));
        const pugi::xml_document document = load_document(source);
        const pugi::xml_node root = scene_root(document, source);
        const FileContext included = make_context(source, root, path.parent_path());
        include_stack_.push_back(identity);
        parse_children(root, included, parent);
        include_stack_.pop_back();
    }

    /// Mitsuba 3's <path value="..."/>: a directory searched for files named by relative paths,
    /// before the others (FileResolver::prepend). Only directly inside the root <scene>; a
    /// relative value is taken from the file's directory, else from the search path.
    void parse_search_path(const pugi::xml_node& element, const FileContext& context,
                           const FileLoc& loc, int parent) {
        const std::string value = required_attribute(element, "value", loc);
        reject_children(element, context);
        if (parent != scene_.root) throw InputError(loc, "<path> can only be a child of <scene>");
        fs::path directory(value);
        if (directory.is_relative()) {
            directory = (context.directory / directory).lexically_normal();
            std::error_code error;
            if (!fs::is_directory(directory, error))
                directory = resolve_path(value, context.directory);
        }
        std::error_code error;
        if (!fs::is_directory(directory, error))
            throw InputError(loc, "<path>: folder " + in_quotes(directory.string()) + " not found");
        search_paths_.insert(search_paths_.begin(), directory);
    }

    /// An included file, as Mitsuba 3 finds it: beside the including file, else beside the
    /// files that include that one (the innermost first: an include names "include/x.xml" and
    /// that file "include/y.xml", both from the scene's directory), else on the search path.
    fs::path resolve_include(const std::string& filename, const fs::path& directory) const {
        const fs::path path(filename);
        if (path.is_absolute()) return path;
        std::error_code error;
        const fs::path own = directory.empty() ? path : (directory / path).lexically_normal();
        if (fs::exists(own, error)) return own;
        for (auto file = include_stack_.rbegin(); file != include_stack_.rend(); ++file) {
            fs::path candidate = (fs::path(*file).parent_path() / path).lexically_normal();
            if (fs::exists(candidate, error)) return candidate;
        }
        return resolve_path(filename, directory);
    }

    /// A relative file name, looked for as Mitsuba 3 looks for it: in the <path> directories
    /// (the latest first), then in the scene file's directory; then, beyond Mitsuba, beside the
    /// included file that names it, so that an include living elsewhere finds its meshes and
    /// textures. Found nowhere: the last (whose absence the reader reports).
    fs::path resolve_path(const std::string& filename, const fs::path& directory) const {
        const fs::path path(filename);
        if (path.is_absolute()) return path;
        const fs::path own = directory.empty() ? path : (directory / path).lexically_normal();
        std::error_code error;
        for (const fs::path& base : search_paths_) {
            fs::path candidate = (base / path).lexically_normal();
            if (fs::exists(candidate, error)) return candidate;
        }
        const fs::path scene_directory = fs::path(scene_.scene_file).parent_path();
        if (scene_directory != directory) {
            // (An empty directory: the scene file is in the working directory.)
            fs::path candidate = (scene_directory / path).lexically_normal();
            if (fs::exists(candidate, error)) return candidate;
        }
        return own;
    }

    // --- properties -----------------------------------------------------------------------

    Property parse_property(const pugi::xml_node& element, const FileContext& context,
                            const FileLoc& loc) const {
        const std::string tag = element.name();
        Property property;
        property.name = property_name(element, context, loc);
        property.loc = loc;
        const std::string what = "<" + tag + " name=\"" + property.name + "\">";

        if (tag == "transform") {
            property.value = TransformValue{parse_transform(element, context)};
            return property;
        }
        reject_children(element, context, /*allow_text=*/tag == "spectrum");
        if (tag == "integer") {
            property.value = parse_int64(required_attribute(element, "value", loc), loc, what);
        } else if (tag == "float") {
            property.value = parse_double(required_attribute(element, "value", loc), loc, what);
        } else if (tag == "boolean") {
            property.value = parse_bool(required_attribute(element, "value", loc), loc, what);
        } else if (tag == "string") {
            std::string value = required_attribute(element, "value", loc);
            // Paths are relative to the file they are written in, so included files that
            // live elsewhere still find their meshes and textures.
            // (a "filename" is resolved against the search path once the scene is read).
            property.value = std::move(value);
        } else if (tag == "rgb" || tag == "srgb") {
            property.value =
                parse_rgb(required_attribute(element, "value", loc), tag == "srgb", loc, what);
        } else if (tag == "spectrum") {
            std::optional<std::string> value = attribute(element, "value", loc);
            if (!value) {
                if (element.attribute("filename"))
                    throw InputError(loc,
                                     "<spectrum filename=...> is not supported; give "
                                     "value=\"lambda:value, ...\"");
                // 0.6 files sometimes put the values in the element text.
                value = substitute(trim(element.text().get()), loc);
            }
            if (is_blank(*value))
                throw InputError(loc, what + " is missing the required 'value' attribute");
            property.value = SpectrumValue{std::string(trim(*value))};
        } else if (tag == "point" || tag == "vector") {
            property.value = Vec3Value{parse_vec3_attributes(element, loc, what, 0.0, true)};
        }
        return property;
    }

    static RgbValue parse_rgb(const std::string& text, bool srgb, const FileLoc& loc,
                              const std::string& what) {
        const std::string_view trimmed = trim(text);
        if (!trimmed.empty() && trimmed.front() == '#')
            return RgbValue{parse_hex_color(trimmed, loc, what), true};
        const std::vector<double> numbers = parse_numbers(trimmed, loc, what);
        if (numbers.size() == 1) return RgbValue{Vec3d::Constant(numbers[0]), srgb};
        if (numbers.size() == 3) return RgbValue{Vec3d(numbers[0], numbers[1], numbers[2]), srgb};
        throw InputError(
            loc, "expected 1 or 3 numbers in " + what + ", got " + std::to_string(numbers.size()));
    }

    /// `value="x, y, z"` (or a single number when `allow_single` and it means all three), or
    /// 0.6-style `x=`, `y=`, `z=` attributes with a default for the missing ones.
    Vec3d parse_vec3_attributes(const pugi::xml_node& element, const FileLoc& loc,
                                const std::string& what, double default_component,
                                bool allow_single) const {
        const std::optional<std::string> value = attribute(element, "value", loc);
        const bool has_components =
            element.attribute("x") || element.attribute("y") || element.attribute("z");
        if (value) {
            if (has_components)
                throw InputError(loc, what + ": give either value= or x=/y=/z=, not both");
            const std::vector<double> numbers = parse_numbers(*value, loc, what);
            if (numbers.size() == 3) return Vec3d(numbers[0], numbers[1], numbers[2]);
            if (numbers.size() == 1 && allow_single) return Vec3d::Constant(numbers[0]);
            throw InputError(loc, "expected " + std::string(allow_single ? "1 or 3" : "3") +
                                      " numbers in " + what + ", got " +
                                      std::to_string(numbers.size()));
        }
        Vec3d result = Vec3d::Constant(default_component);
        const char* const keys[] = {"x", "y", "z"};
        for (int axis = 0; axis < 3; ++axis)
            if (std::optional<std::string> component = attribute(element, keys[axis], loc))
                result[axis] = parse_double(*component, loc, what);
        return result;
    }

    /// Operations are applied in the order written: each is left-multiplied onto the result
    /// so far, M = T_k * ... * T_1.
    Mat4d parse_transform(const pugi::xml_node& element, const FileContext& context) const {
        Mat4d world_from_object = Mat4d::Identity();
        for (const pugi::xml_node& child : element.children()) {
            if (child.type() != pugi::node_element) {
                reject_text(child, context);
                continue;
            }
            world_from_object = parse_transform_operation(child, context) * world_from_object;
        }
        return world_from_object;
    }

    Mat4d parse_transform_operation(const pugi::xml_node& element,
                                    const FileContext& context) const {
        const std::string tag = element.name();
        const FileLoc loc = context.source->loc_of(element);
        const std::string what = "<" + tag + ">";
        if (!is_transform_operation_tag(tag))
            throw InputError(loc, "<" + tag + "> is not allowed inside <transform>");
        reject_children(element, context);

        Mat4d m = Mat4d::Identity();
        if (tag == "translate") {
            m.block<3, 1>(0, 3) = parse_vec3_attributes(element, loc, what, 0.0, false);
        } else if (tag == "scale") {
            m.diagonal().head<3>() = parse_vec3_attributes(element, loc, what, 1.0, true);
        } else if (tag == "rotate") {
            const Vec3d axis = parse_vec3_attributes(element, loc, what, 0.0, false);
            const double degrees =
                parse_double(required_attribute(element, "angle", loc), loc, what);
            if (!(axis.norm() > 0.0)) throw InputError(loc, "<rotate> needs a non-zero axis");
            const double radians = degrees * (std::numbers::pi / 180.0);
            if (context.legacy_names) {
                // Mitsuba 0.6 normalises the axis.
                m.block<3, 3>(0, 0) =
                    Eigen::AngleAxisd(radians, axis.normalized()).toRotationMatrix();
            } else {
                // Mitsuba 2 and 3 do not (drjit's rotate: c I + (1 - c) a a^T + s [a]x with the
                // axis as written), so a non-unit axis also scales and shears: Mitsuba 3's own
                // scenes/hello.xml rotates its teapot about (0, 1, 1), a matrix of determinant
                // 1.10. As written means as Mitsuba 3 reads it.
                const double c = std::cos(radians), s = std::sin(radians);
                Eigen::Matrix3d cross;
                cross << 0.0, -axis.z(), axis.y(), axis.z(), 0.0, -axis.x(), -axis.y(), axis.x(),
                    0.0;
                m.block<3, 3>(0, 0) = c * Eigen::Matrix3d::Identity() +
                                      (1.0 - c) * axis * axis.transpose() + s * cross;
            }
        } else if (tag == "matrix") {
            const std::vector<double> numbers =
                parse_numbers(required_attribute(element, "value", loc), loc, what);
            if (numbers.size() == 16) {
                for (int row = 0; row < 4; ++row)
                    for (int col = 0; col < 4; ++col)
                        m(row, col) = numbers[static_cast<std::size_t>(4 * row + col)];
            } else if (numbers.size() == 9) {
                for (int row = 0; row < 3; ++row)
                    for (int col = 0; col < 3; ++col)
                        m(row, col) = numbers[static_cast<std::size_t>(3 * row + col)];
            } else {
                throw InputError(loc, "<matrix> needs 16 (4x4) or 9 (3x3) numbers, got " +
                                          std::to_string(numbers.size()));
            }
        } else {  // lookat
            const Vec3d origin =
                parse_three_numbers(required_attribute(element, "origin", loc), loc, what);
            const Vec3d target =
                parse_three_numbers(required_attribute(element, "target", loc), loc, what);
            std::optional<Vec3d> up;
            if (std::optional<std::string> up_text = attribute(element, "up", loc))
                up = parse_three_numbers(*up_text, loc, what);
            m = look_at_matrix(origin, target, up, loc);
        }
        return m;
    }

    SceneDesc scene_;
    std::map<std::string, std::string> parameters_;  // -D defines, then <default>s
    std::map<std::string, int> ids_;                 // id or alias -> object index
    std::vector<std::string> include_stack_;         // files being parsed, outermost first
    std::vector<fs::path> search_paths_;             // <path> directories, the latest first
    /// A "filename" property as written, resolved when the whole scene has been read.
    struct PendingFilename {
        int object = -1;
        std::size_t property = 0;  // index in the object's properties
        std::string written;
        fs::path directory;  // of the file it is written in
    };
    std::vector<PendingFilename> pending_filenames_;
    /// A <ref>: the object holding it, its index among that object's children, the id.
    struct PendingRef {
        int object = -1;
        std::size_t child = 0;
        std::string id;
    };
    std::vector<PendingRef> pending_refs_;
    static constexpr int kMaxObjectNesting = 256;
    static constexpr int kMaxIncludes = 10000;
    int includes_ = 0;      // <include> elements processed so far, repeats counted
    int object_depth_ = 0;  // objects being parsed, includes counted through
};

}  // namespace

SceneDesc parse_scene_file(const std::string& path, const ParseOptions& options) {
    std::string why;
    std::optional<std::string> text = read_text_file(path, why);
    if (!text) throw InputError(FileLoc{path, 0, 0}, "cannot open scene file: " + why);
    return SceneParser(options).parse(std::move(*text), path);
}

SceneDesc parse_scene_string(const std::string& xml, const std::string& virtual_path,
                             const ParseOptions& options) {
    return SceneParser(options).parse(xml, virtual_path);
}

}  // namespace gdmlt
