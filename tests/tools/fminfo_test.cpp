// fminfo on files whose settings (informative JSON the file chooses, spec/container.md §5) it must
// not walk: nested deeper than its limit of 64 levels, 1 MiB of brackets (which crashed
// fminfo --json: SIGSEGV after 35 s and 3.9 GB), or not JSON at all. fminfo describes the rest of
// the file, leaves the settings out and says so naming the file; it never crashes. And the version
// a file with frame patches needs.
#include "codec/writer/container/sequence_file_writer.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#ifndef FACEMORPH_FMINFO
#error "FACEMORPH_FMINFO must name the fminfo program"
#endif

namespace {

using facemorph::testing::TempDir;

// A small valid file with these settings.
std::filesystem::path file_with_settings(const TempDir& dir, const std::string& settings) {
  facemorph::SequenceFileMetadata metadata = facemorph::crafted::small_metadata();
  metadata.settings = settings;
  const std::filesystem::path path = dir / "settings.fmv";
  facemorph::write_sequence_file(path, facemorph::crafted::small_sequence(), metadata);
  return path;
}

// `levels` arrays, one inside the other, in an object: {"nest": [[...]]} nests levels + 1 deep.
std::string nested(size_t levels) { return "{\"nest\":" + std::string(levels, '[') + std::string(levels, ']') + "}"; }

struct FminfoRun {
  int status = -1;  // the exit status, or -1 when fminfo did not exit (a signal)
  std::string out, err;
};

std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

FminfoRun fminfo(const TempDir& dir, const std::filesystem::path& file, bool json, const std::string& options = "") {
  const std::string command = std::string("\"") + FACEMORPH_FMINFO + "\" " + (json ? "--json " : "") + options + "\"" + file.string() + "\" > \"" +
                              (dir / "out").string() + "\" 2> \"" + (dir / "err").string() + "\"";
  const int raw = std::system(command.c_str());
  FminfoRun run;
  run.status = raw != -1 && WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.out = slurp(dir / "out");
  run.err = slurp(dir / "err");
  return run;
}

// The description fminfo --json printed, or a failure saying why it is not JSON.
nlohmann::json described(const FminfoRun& run) {
  nlohmann::json doc = nlohmann::json::parse(run.out, nullptr, false);
  EXPECT_FALSE(doc.is_discarded()) << "fminfo --json printed no JSON:\n" << run.out.substr(0, 2000);
  return doc;
}

TEST(Fminfo, SettingsNestedAtTheLimitAreShown) {
  TempDir dir;
  const std::string settings = nested(63);  // 64 levels: the object and 63 arrays
  const auto file = file_with_settings(dir, settings);
  const FminfoRun run = fminfo(dir, file, true);
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
  const nlohmann::json doc = described(run);
  EXPECT_EQ(doc["settings"], nlohmann::json::parse(settings));
  EXPECT_FALSE(doc.contains("settings_error"));
}

TEST(Fminfo, SettingsNestedDeeperAreLeftOutNamingTheFile) {
  TempDir dir;
  const auto file = file_with_settings(dir, nested(64));  // 65 levels
  for (const bool json : {true, false}) {
    SCOPED_TRACE(json ? "--json" : "text");
    const FminfoRun run = fminfo(dir, file, json);
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_NE(run.err.find("fminfo: warning: " + file.string() + ": the settings are nested deeper than 64 levels"), std::string::npos)
        << run.err;
    if (json) {
      const nlohmann::json doc = described(run);
      EXPECT_TRUE(doc["settings"].is_null());
      EXPECT_NE(doc.value("settings_error", "").find("nested deeper than 64 levels"), std::string::npos) << doc.dump();
      EXPECT_EQ(doc["keyframes"].size(), 3u);  // the rest of the description stands
    } else {
      EXPECT_NE(run.out.find("settings    left out: nested deeper than 64 levels"), std::string::npos) << run.out.substr(0, 2000);
      EXPECT_NE(run.out.find("keyframes   3"), std::string::npos);
    }
  }
}

// The review's file: 524,288 levels, the 1 MiB a header string may take (the writer's and the
// reader's bound). Without the limit fminfo --json ran 35 s into 3.9 GB and died of its stack.
TEST(Fminfo, SettingsOfOneMebibyteOfBracketsDoNotCrashIt) {
  TempDir dir;
  const std::string settings = std::string(size_t{1} << 19, '[') + std::string(size_t{1} << 19, ']');
  ASSERT_EQ(settings.size(), size_t{1} << 20);
  const auto file = file_with_settings(dir, settings);
  for (const bool json : {true, false}) {
    SCOPED_TRACE(json ? "--json" : "text");
    const FminfoRun run = fminfo(dir, file, json);
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_NE(run.err.find(file.string() + ": the settings are nested deeper than 64 levels"), std::string::npos) << run.err;
    if (json) {
      EXPECT_TRUE(described(run)["settings"].is_null());
    }
  }
}

// Settings that do not parse were printed as `"settings": <discarded>`, which is not JSON.
TEST(Fminfo, SettingsThatAreNotJsonAreLeftOutAndTheOutputStaysJson) {
  TempDir dir;
  const auto file = file_with_settings(dir, "{\"keyframes\": ");
  const FminfoRun run = fminfo(dir, file, true);
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.err.find(file.string() + ": the settings are not JSON"), std::string::npos) << run.err;
  const nlohmann::json doc = described(run);
  EXPECT_TRUE(doc["settings"].is_null());
}

// The version a file with frame patches needs is the one of its PTCH's coding (spec/container.md
// §7.5.1): 2.5's range-coded stream in a file of this writer, 2.4's varints in golden_v2_4.fmv.
TEST(Fminfo, AFileWithPatchesNeedsTheVersionOfItsPatchCoding) {
  TempDir dir;
  facemorph::Sequence patched = facemorph::crafted::small_sequence(9, 8);
  patched.patches = {{0.25, 3, {4}, {facemorph::Vec3(0.0625, 0, 0)}}};
  const std::filesystem::path file = dir / "patched.fmv";
  facemorph::write_sequence_file(file, patched, facemorph::crafted::small_metadata());
  const FminfoRun run = fminfo(dir, file, true);
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(described(run)["format_version_needed"], "2.5");
  const FminfoRun golden = fminfo(dir, std::string(FACEMORPH_TEST_DATA) + "/golden_v2_4.fmv", true);
  ASSERT_EQ(golden.status, 0) << golden.err;
  EXPECT_EQ(described(golden)["format_version_needed"], "2.4");
  // A KGLV chunk (the levels predictor, 2.6) needs 2.6; the patched file above, all KGOP, 2.5.
  const FminfoRun levels = fminfo(dir, std::string(FACEMORPH_TEST_DATA) + "/golden_v2_6.fmv", true);
  ASSERT_EQ(levels.status, 0) << levels.err;
  EXPECT_EQ(described(levels)["format_version_needed"], "2.6");
}

// fminfo --field-bytes costs each keyframe as the file's writer did, among its version's predictors
// (spec/container.md §10.5): golden_v2_4.fmv's writer had no linear predictor along the rim, so its
// estimate is its KGOP bytes (1339.8 B for 1328); the same groups stamped 2.5 are costed with linear
// (the rim's 310.2 B become 178.2 B, the whole 1207.8 B, 9% under the chunk).
TEST(Fminfo, FieldBytesCostsAFileUnderItsOwnVersionsPredictors) {
  TempDir dir;
  const std::filesystem::path old_file = std::filesystem::path(FACEMORPH_TEST_DATA) / "golden_v2_4.fmv";
  const std::filesystem::path restamped = dir / "golden_stamped_2_5.fmv";
  {
    const std::string bytes = slurp(old_file);
    // Its PTCH (2.4's varints) set aside as a chunk no decoder knows: 2.5 reads a PTCH range-coded.
    const std::vector<uint8_t> without_patches =
        facemorph::crafted::rebuild(std::vector<uint8_t>(bytes.begin(), bytes.end()), [](std::string& type, std::vector<uint8_t>&) {
          if (type == "PTCH") type = "ZPTC";
        });
    const std::vector<uint8_t> as_2_5 = facemorph::crafted::restamped(without_patches, 5);
    std::ofstream(restamped, std::ios::binary).write(reinterpret_cast<const char*>(as_2_5.data()), static_cast<std::streamsize>(as_2_5.size()));
  }
  struct Costed {
    double kgop = 0, fields = 0, rim = 0;
  };
  const auto costed = [&](const std::filesystem::path& file) {
    const FminfoRun run = fminfo(dir, file, true, "--field-bytes ");
    EXPECT_EQ(run.status, 0) << run.err;
    const nlohmann::json doc = described(run);
    Costed c;
    for (const auto& chunk : doc["chunks"]) {
      if (chunk["type"] == "KGOP") c.kgop += chunk["bytes"].get<double>();
    }
    for (const auto& group : doc["field_bytes_by_array"]) {
      c.fields += group["bytes"].get<double>();
      if (group["arrays"] == "rim") c.rim = group["bytes"].get<double>();
    }
    return c;
  };
  const Costed as_2_4 = costed(old_file), as_2_5 = costed(restamped);
  EXPECT_NEAR(as_2_4.fields / as_2_4.kgop, 1.0, 0.03) << as_2_4.fields << " B estimated, " << as_2_4.kgop << " B in KGOP";
  EXPECT_LT(as_2_5.rim, 0.7 * as_2_4.rim) << "stamped 2.5, the rim is costed with linear: " << as_2_5.rim << " B against " << as_2_4.rim;
}

// A file whose rim is coded with format 2.5's linear predictor needs 2.5 (stamped 2.6 by this writer,
// it needs no more without a KGLV chunk): fminfo, which decodes no keyframe, must not say it needs an older version (a 2.4 reader refuses its groups, shown here by
// the same bytes stamped 2.4).
TEST(Fminfo, AFileCodedWithLinearAlongTheRimIsNotSaidToNeedAnOlderVersion) {
  TempDir dir;
  const std::filesystem::path file = dir / "now.fmv";
  facemorph::write_sequence_file(file, facemorph::crafted::small_sequence(), facemorph::crafted::small_metadata());
  const FminfoRun run = fminfo(dir, file, false);
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.out.find(", format 2.6 (needs 2.5), written by"), std::string::npos) << run.out.substr(0, 400);  // no KGLV at N = 17
  const std::string bytes = slurp(file);
  const std::filesystem::path old = dir / "stamped_2_4.fmv";
  const std::vector<uint8_t> as_2_4 = facemorph::crafted::restamped(std::vector<uint8_t>(bytes.begin(), bytes.end()), 4);
  std::ofstream(old, std::ios::binary).write(reinterpret_cast<const char*>(as_2_4.data()), static_cast<std::streamsize>(as_2_4.size()));
  const FminfoRun verified = fminfo(dir, old, false, "--verify ");
  EXPECT_EQ(verified.status, 1);
  EXPECT_NE(verified.err.find("has predictor 2, not one for that array in a 2.4 file"), std::string::npos) << verified.err;
}

}  // namespace
