// One table per enumeration: each enumerator beside the name that settings, command lines and files
// use for it (the names are stored: a file's settings and a part file hold them, so a name never
// changes). name_of and parse_name work on any such table, so an enumeration's two directions cannot
// drift apart.
#pragma once

#include "format/error.hpp"

#include <cstddef>
#include <string>
#include <string_view>

namespace facemorph {

template <typename Enum>
struct EnumName {
  Enum value;
  const char* name;
};

// The name of `value` in `table`; "unknown" for a value the table lacks (only a cast makes one).
template <typename Enum, size_t N>
constexpr const char* name_of(const EnumName<Enum> (&table)[N], Enum value) {
  for (const EnumName<Enum>& entry : table) {
    if (entry.value == value) return entry.name;
  }
  return "unknown";
}

// The enumerator `table` names `name`. Throws kInvalidArgument "unknown WHAT 'NAME' (every name,
// comma-separated)" for any other name.
template <typename Enum, size_t N>
Enum parse_name(const EnumName<Enum> (&table)[N], std::string_view name, const char* what) {
  std::string names;
  for (const EnumName<Enum>& entry : table) {
    if (name == entry.name) return entry.value;
    names += (names.empty() ? "" : ", ") + std::string(entry.name);
  }
  throw Error(ErrorCode::kInvalidArgument, "unknown " + std::string(what) + " '" + std::string(name) + "' (" + names + ")");
}

}  // namespace facemorph
