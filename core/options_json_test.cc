#include "core/options_json.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace sightmap {
namespace {

enum class Shape { kRound, kSquare };
const std::pair<Shape, const char*> kShapeNames[] = {{Shape::kRound, "round"},
                                                     {Shape::kSquare, "square"}};
void to_json(nlohmann::json& json, const Shape& shape) {
  options_json::WriteEnum(json, shape, kShapeNames);
}
void from_json(const nlohmann::json& json, Shape& shape) {
  options_json::ReadEnum(json, shape, kShapeNames);
}

struct InnerOptions {
  int count = 3;
  double scale_m = 0.5;
};
SIGHTMAP_OPTIONS_JSON(InnerOptions, count, scale_m)

struct OuterOptions {
  std::string name = "walk";
  bool enabled = true;
  uint64_t seed = 7;
  int64_t start_frame = 0;
  std::vector<int> levels = {1, 2};
  Shape shape = Shape::kRound;
  Eigen::Vector3d up = Eigen::Vector3d(0.0, -1.0, 0.0);
  InnerOptions inner;
};
SIGHTMAP_OPTIONS_JSON(OuterOptions, name, enabled, seed, start_frame, levels, shape, up, inner)

// A struct listed in two parts, as one of more than 63 fields must be.
struct SplitOptions {
  int first = 1;
  double second_m = 2.0;
  bool third = false;
};
SIGHTMAP_OPTIONS_JSON_LONG(SplitOptions, (first, second_m), (third))

// The message of the error reading `text` into default options.
std::string ReadError(const std::string& text) {
  OuterOptions options;
  try {
    options_json::ParseInto(text, "config.json", options);
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

TEST(OptionsJson, WritesEveryFieldUnderItsName) {
  const nlohmann::json json = OuterOptions();
  EXPECT_EQ(json.dump(),
            R"({"enabled":true,"inner":{"count":3,"scale_m":0.5},"levels":[1,2],"name":"walk",)"
            R"("seed":7,"shape":"round","start_frame":0,"up":[0.0,-1.0,0.0]})");
}

TEST(OptionsJson, ReadsBackWhatItWrote) {
  OuterOptions changed;
  changed.name = "survey";
  changed.enabled = false;
  changed.seed = 18446744073709551615ull;
  changed.start_frame = -4;
  changed.levels = {7};
  changed.shape = Shape::kSquare;
  changed.up = Eigen::Vector3d(0.0, 0.0, 1.0);
  changed.inner.count = 9;
  changed.inner.scale_m = 1e-3;
  const nlohmann::json written = changed;
  OuterOptions read;
  options_json::ParseInto(written.dump(), "config.json", read);
  EXPECT_EQ(read.name, "survey");
  EXPECT_FALSE(read.enabled);
  EXPECT_EQ(read.seed, 18446744073709551615ull);
  EXPECT_EQ(read.start_frame, -4);
  EXPECT_EQ(read.levels, std::vector<int>{7});
  EXPECT_EQ(read.shape, Shape::kSquare);
  EXPECT_EQ(read.up, Eigen::Vector3d(0.0, 0.0, 1.0));
  EXPECT_EQ(read.inner.count, 9);
  EXPECT_EQ(read.inner.scale_m, 1e-3);
  EXPECT_EQ(nlohmann::json(read), written);
}

TEST(OptionsJson, AnAbsentKeyKeepsTheValueAlreadySet) {
  OuterOptions options;
  options.name = "set on the command line";
  options.inner.count = 11;
  options_json::ParseInto(R"({"inner": {"scale_m": 2.0}, "enabled": false})", "config.json",
                          options);
  EXPECT_EQ(options.name, "set on the command line");
  EXPECT_EQ(options.inner.count, 11);
  EXPECT_EQ(options.inner.scale_m, 2.0);
  EXPECT_FALSE(options.enabled);
}

TEST(OptionsJson, AcceptsComments) {
  OuterOptions options;
  options_json::ParseInto("{\n  // a hand-written config\n  \"seed\": 3\n}", "config.json",
                          options);
  EXPECT_EQ(options.seed, 3u);
}

TEST(OptionsJson, NamesTheFullPathOfAnUnknownKeyAndGuessesTheTypo) {
  EXPECT_EQ(ReadError(R"({"inner": {"scale": 1}})"),
            "config.json: inner.scale: unknown option; did you mean scale_m?");
  EXPECT_EQ(ReadError(R"({"colour": "red"})"), "config.json: colour: unknown option");
}

TEST(OptionsJson, AStructListedInTwoPartsReadsAndWritesBothAndKnowsEveryKey) {
  SplitOptions options;
  options.first = 5;
  options.third = true;
  nlohmann::json json = options;
  EXPECT_EQ(json, nlohmann::json::parse(R"({"first": 5, "second_m": 2.0, "third": true})"));
  SplitOptions read;
  options_json::ParseInto(R"({"second_m": 4.5, "third": true})", "config.json", read);
  EXPECT_EQ(read.first, 1);
  EXPECT_EQ(read.second_m, 4.5);
  EXPECT_TRUE(read.third);
  try {
    options_json::ParseInto(R"({"thrid": true})", "config.json", read);
    FAIL() << "an unknown key was read";
  } catch (const InvalidArgument& e) {
    EXPECT_STREQ(e.what(), "config.json: thrid: unknown option; did you mean third?");
  }
}

TEST(OptionsJson, RefusesWhatNlohmannWouldQuietlyConvert) {
  EXPECT_EQ(ReadError(R"({"inner": {"count": 2.5}})"),
            "config.json: inner.count: must be a whole number");
  EXPECT_EQ(ReadError(R"({"seed": -1})"), "config.json: seed: must not be negative");
  EXPECT_EQ(ReadError(R"({"inner": {"count": 3000000000}})"),
            "config.json: inner.count: is too large");
  EXPECT_EQ(ReadError(R"({"inner": {"count": -3000000000}})"),
            "config.json: inner.count: is out of range");
  EXPECT_EQ(ReadError(R"({"enabled": 1})"), "config.json: enabled: must be true or false");
  EXPECT_EQ(ReadError(R"({"name": 5})"), "config.json: name: must be a string");
  EXPECT_EQ(ReadError(R"({"inner": {"scale_m": "far"}})"),
            "config.json: inner.scale_m: must be a number");
  EXPECT_EQ(ReadError(R"({"shape": "oval"})"), "config.json: shape: must be one of round, square");
  EXPECT_EQ(ReadError(R"({"up": [0, 1]})"), "config.json: up: must be an array of 3 numbers");
  EXPECT_EQ(ReadError(R"({"levels": [1, "two"]})"),
            "config.json: levels[1]: must be a whole number");
  EXPECT_EQ(ReadError(R"({"levels": [2.5]})"), "config.json: levels[0]: must be a whole number");
  // Whole, but written as a float too large for any count: out of range, not "not whole".
  EXPECT_EQ(ReadError(R"({"inner": {"count": 1e300}})"),
            "config.json: inner.count: is out of range: must be from -2147483648 to 2147483647");
  EXPECT_EQ(ReadError(R"({"seed": -1e30})"),
            "config.json: seed: is out of range: must be from 0 to 18446744073709551615");
  EXPECT_EQ(ReadError(R"({"levels": [1e10]})"),
            "config.json: levels[0]: is out of range: must be from -2147483648 to 2147483647");
  EXPECT_EQ(ReadError(R"({"levels": 3})"), "config.json: levels: must be an array of numbers");
  EXPECT_EQ(ReadError(R"({"inner": 4})"), "config.json: inner: must be an object ({...})");
  EXPECT_EQ(ReadError("[1, 2]"), "config.json: must be an object ({...})");
}

TEST(OptionsJson, ABrokenFileSaysWhereItBreaks) {
  const std::string message = ReadError("{\n  \"seed\": 3,\n}");
  EXPECT_EQ(message.rfind("config.json is not valid JSON: parse error at line 3", 0), 0u)
      << message;
  EXPECT_EQ(message.find("json.exception"), std::string::npos) << message;
}

TEST(OptionsJson, ANumberBeyondDoubleIsABrokenFileNotACrash) {
  // Found by the options_json fuzzer: nlohmann throws out_of_range, not parse_error, for it.
  EXPECT_EQ(ReadError("22e888").rfind("config.json is not valid JSON: number overflow", 0), 0u)
      << ReadError("22e888");
  EXPECT_EQ(ReadError(R"({"inner": {"scale_m": 1e999}})")
                .rfind("config.json is not valid JSON: number overflow", 0),
            0u);
}

TEST(OptionsJson, AFailedReadNamesOnlyTheFirstProblem) {
  // One line for the user, however many mistakes the file holds.
  const std::string message = ReadError(R"({"seed": "x", "colour": 1})");
  EXPECT_EQ(message.find('\n'), std::string::npos);
}

}  // namespace
}  // namespace sightmap
