// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Typed reading of an element's properties that remembers what was read, so that whatever is
// left unread (misspelt or unsupported) can be reported with its file and line (pbrt-v4's
// ReportUnused, Mitsuba's unqueried-property error). Used by modules that read their own
// knobs from the scene, e.g. the MLT integrators from <integrator type="pssmlt">.
#include <initializer_list>
#include <set>
#include <string>

#include "core/scene/scene_desc.h"

namespace gdmlt {

class PropertyReader {
  public:
    explicit PropertyReader(const ObjectDesc& object) : object_(object) {}

    bool has(const std::string& name) const { return object_.find(name) != nullptr; }
    double get_float(const std::string& name, double fallback);
    std::int64_t get_int(const std::string& name, std::int64_t fallback);
    /// get_int for an int: out of 32-bit range is an InputError (checked_int32).
    int get_int32(const std::string& name, int fallback) {
        return checked_int32(get_int(name, fallback), name, loc_of(name));
    }
    bool get_bool(const std::string& name, bool fallback);
    std::string get_string(const std::string& name, const std::string& fallback);
    /// Location of a property (of the element when absent), for errors about its value.
    const FileLoc& loc_of(const std::string& name) const;

    /// Declares properties read elsewhere.
    void mark_read(std::initializer_list<const char*> names);
    /// Throws InputError at the first property nobody read.
    void check_all_read() const;

  private:
    const Property* take(const std::string& name);
    [[noreturn]] void mismatch(const Property& p, const char* expected) const;

    const ObjectDesc& object_;
    std::set<std::string> read_;
};

}  // namespace gdmlt
