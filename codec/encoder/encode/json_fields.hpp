// Reading the JSON an encode stage wrote (a part file's header, a segment's measure): parsed with
// a bound on nesting, each field checked for its type. A file is untrusted, so every error is
// kCorrupt saying which field of `what` ("its header") is wrong; the caller names the file.
#pragma once

#include "format/error.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <limits>
#include <string>

namespace facemorph::json_fields {

[[noreturn]] inline void bad(const std::string& what) { throw Error(ErrorCode::kCorrupt, what); }

// A JSON object from `text`, nesting at most `max_depth` levels (a reader, and dump, recurse).
template <typename Bytes>
nlohmann::json parse_object(const Bytes& text, int max_depth, const std::string& what) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text.begin(), text.end(), [&](int depth, nlohmann::json::parse_event_t, nlohmann::json&) {
      if (depth > max_depth) bad(what + " nests deeper than " + std::to_string(max_depth));
      return true;
    });
  } catch (const nlohmann::json::exception& e) {
    bad(what + " is not JSON: " + e.what());
  }
  if (!doc.is_object()) bad(what + " is not a JSON object");
  return doc;
}

template <typename T>
T field(const nlohmann::json& doc, const char* name, const std::string& what) {
  if (!doc.contains(name)) bad(what + " lacks \"" + name + "\"");
  try {
    return doc.at(name).get<T>();
  } catch (const nlohmann::json::exception&) {
    bad(what + "'s \"" + name + "\" is not what it should be");
  }
}

// A whole number that fits an int (a JSON number with a fraction, or past int's range, is refused).
inline int integer_field(const nlohmann::json& doc, const char* name, const std::string& what) {
  if (!doc.contains(name)) bad(what + " lacks \"" + name + "\"");
  const nlohmann::json& value = doc.at(name);
  if (!value.is_number_integer()) bad(what + "'s \"" + name + "\" is not a whole number");
  if (value.is_number_unsigned() && value.get<uint64_t>() > static_cast<uint64_t>(std::numeric_limits<int>::max()))
    bad(what + "'s \"" + name + "\" is out of range");
  const auto number = value.get<int64_t>();
  if (number < std::numeric_limits<int>::min() || number > std::numeric_limits<int>::max())
    bad(what + "'s \"" + name + "\" is out of range");
  return static_cast<int>(number);
}

}  // namespace facemorph::json_fields
