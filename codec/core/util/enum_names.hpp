// One table per enumeration: each enumerator beside the name that settings, command lines and files
// use for it (the names are stored: a file's settings and a part file hold them, so a name never
// changes), and, for an enumeration a file also stores as a number, beside that number too. name_of
// and parse_name work on any such table, code_of and enum_of on a coded one, so an enumeration's
// directions (value <-> name, value <-> file code) cannot drift apart.
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

// An enumerator of an enumeration that a file stores as a number: its name and its file code
// (spec/container.md §5, §8), fixed forever and independent of the order of the C++ enumerators.
// `Code` is the integer type the file stores it in.
template <typename Enum, typename Code>
struct CodedEnumName {
  Enum value;
  const char* name;
  Code code;
};

// The name of `value` in `table`; "unknown" for a value the table lacks (only a cast makes one).
template <typename Entry, size_t N>
constexpr const char* name_of(const Entry (&table)[N], decltype(Entry::value) value) {
  for (const Entry& entry : table) {
    if (entry.value == value) return entry.name;
  }
  return "unknown";
}

// The enumerator `table` names `name`. Throws kInvalidArgument "unknown WHAT 'NAME' (every name,
// comma-separated)" for any other name.
template <typename Entry, size_t N>
decltype(Entry::value) parse_name(const Entry (&table)[N], std::string_view name, const char* what) {
  std::string names;
  for (const Entry& entry : table) {
    if (name == entry.name) return entry.value;
    names += (names.empty() ? "" : ", ") + std::string(entry.name);
  }
  throw Error(ErrorCode::kInvalidArgument, "unknown " + std::string(what) + " '" + std::string(name) + "' (" + names + ")");
}

// The file code of `value`; kInvalidArgument for a value the table lacks (only a cast makes one).
template <typename Enum, typename Code, size_t N>
constexpr Code code_of(const CodedEnumName<Enum, Code> (&table)[N], Enum value) {
  for (const CodedEnumName<Enum, Code>& entry : table) {
    if (entry.value == value) return entry.code;
  }
  throw Error(ErrorCode::kInvalidArgument, "no file code for an enumerator");
}

// The entry whose file code is `code`, or null: for a reader that words its own refusal.
template <typename Enum, typename Code, size_t N>
constexpr const CodedEnumName<Enum, Code>* entry_of_code(const CodedEnumName<Enum, Code> (&table)[N], Code code) {
  for (const CodedEnumName<Enum, Code>& entry : table) {
    if (entry.code == code) return &entry;
  }
  return nullptr;
}

// The enumerator a file states as `code`. Throws kUnsupported "WHAT CODE is not one this decoder
// knows" for any other code (a later format's, or a damaged file's).
template <typename Enum, typename Code, size_t N>
Enum enum_of(const CodedEnumName<Enum, Code> (&table)[N], Code code, const std::string& what) {
  if (const CodedEnumName<Enum, Code>* entry = entry_of_code(table, code)) return entry->value;
  throw Error(ErrorCode::kUnsupported, what + " " + std::to_string(code) + " is not one this decoder knows");
}

// True when no two entries of `table` share a value, a name or a file code: checked where each
// coded table is defined (static_assert), so that a pasted row cannot map two ways.
template <typename Enum, typename Code, size_t N>
constexpr bool is_one_to_one(const CodedEnumName<Enum, Code> (&table)[N]) {
  for (size_t i = 0; i < N; ++i) {
    for (size_t j = i + 1; j < N; ++j) {
      if (table[i].value == table[j].value || table[i].code == table[j].code ||
          std::string_view(table[i].name) == std::string_view(table[j].name))
        return false;
    }
  }
  return true;
}

}  // namespace facemorph
