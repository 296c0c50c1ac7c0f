// The encode options as a stage stores them beside its output, so that a later stage can tell
// whether it runs with the options the earlier one ran with: one schema, whose field list both the
// writer and the reader follow (options_json.cpp). A part file's header holds the sample stage's
// (spec/part-file.md), a segment's measure the sample's and the assemble stage's (segmented_encode.hpp).
// What a file's header states of its encode (informative, with what was chosen) is another record:
// encode_settings.hpp.
#pragma once

#include "codec/encoder/encode/encode_options.hpp"

#include <string>
#include <string_view>

namespace facemorph {

enum class OptionsScope {
  kSample,   // what the map, register and sample stages depend on: a part file's
  kSegment,  // kSample's (under "sample") and what the keyframes' planning and coding depend on: a measure's
};

// `options`' fields of `scope` as a JSON object (keys sorted; enumerations as their numbers, the
// representation by name): the bytes part files and measures have always stored.
std::string write_options(const EncodeOptions& options, OptionsScope scope);

// What write_options wrote, read onto `options` (the fields of `scope` replaced, the others kept).
// kCorrupt naming the field where `text` is no such object (a field missing, of another type, an
// enumeration out of its range).
EncodeOptions read_options(std::string_view text, OptionsScope scope, EncodeOptions options = {});

// Whether `stored` (write_options's, as a file holds it) states the same options of `scope` as
// `options`: compared as JSON values, so neither the keys' order nor how a number was formatted
// matters; a key more or less does. False where `stored` is not a JSON object.
bool same_options(std::string_view stored, const EncodeOptions& options, OptionsScope scope);
// The same comparison of `stored` with `written` (write_options's of the options it is held to):
// for a caller that checks many stored settings against one encode's, its options written once.
bool same_options(std::string_view stored, std::string_view written);

}  // namespace facemorph
