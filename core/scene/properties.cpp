// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/properties.h"

namespace gdmlt {

const Property* PropertyReader::take(const std::string& name) {
    const Property* p = object_.find(name);
    if (p) read_.insert(name);
    return p;
}

void PropertyReader::mismatch(const Property& p, const char* expected) const {
    throw InputError(p.loc, "property '" + p.name + "' of <" + object_.tag + " type=\"" +
                                object_.type + "\"> should be " + expected);
}

double PropertyReader::get_float(const std::string& name, double fallback) {
    const Property* p = take(name);
    if (!p) return fallback;
    if (const auto* d = std::get_if<double>(&p->value)) return *d;
    if (const auto* i = std::get_if<std::int64_t>(&p->value)) return static_cast<double>(*i);
    mismatch(*p, "a float");
}

std::int64_t PropertyReader::get_int(const std::string& name, std::int64_t fallback) {
    const Property* p = take(name);
    if (!p) return fallback;
    if (const auto* i = std::get_if<std::int64_t>(&p->value)) return *i;
    mismatch(*p, "an integer");
}

bool PropertyReader::get_bool(const std::string& name, bool fallback) {
    const Property* p = take(name);
    if (!p) return fallback;
    if (const auto* b = std::get_if<bool>(&p->value)) return *b;
    mismatch(*p, "a boolean");
}

std::string PropertyReader::get_string(const std::string& name, const std::string& fallback) {
    const Property* p = take(name);
    if (!p) return fallback;
    if (const auto* s = std::get_if<std::string>(&p->value)) return *s;
    mismatch(*p, "a string");
}

const FileLoc& PropertyReader::loc_of(const std::string& name) const {
    const Property* p = object_.find(name);
    return p ? p->loc : object_.loc;
}

void PropertyReader::mark_read(std::initializer_list<const char*> names) {
    for (const char* n : names) read_.insert(n);
}

void PropertyReader::check_all_read() const {
    for (const Property& p : object_.properties)
        if (!read_.count(p.name))
            throw InputError(p.loc, "unknown property '" + p.name + "' in <" + object_.tag +
                                        " type=\"" + object_.type + "\">");
}

}  // namespace gdmlt
