// Every options struct that `map`, `locate` and `serve` run with, through JSON and back: what the
// model's session row stores and `--config` reads must give back the very same options.
#include <map>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/label_service.h"
#include "cli/locate_server.h"
#include "core/options_json.h"
#include "identify/labels.h"
#include "identify/locator.h"
#include "mapping/mapping_session.h"

namespace sightmap {
namespace {

// The names enums are changed to, by key (every other leaf is changed by its type).
const std::map<std::string, std::string> kOtherEnumName = {{"type", "sift"},
                                                           {"choice", "headless"},
                                                           {"matcher", "rootsift"},
                                                           {"retrieval", "bag_of_words"},
                                                           {"second_look_retrieval", "vlad"}};

// `json` with every leaf changed: whole numbers + 1, other numbers x 1.5 + 0.25, flags flipped,
// strings extended, enums to another name.
nlohmann::json ChangeEveryLeaf(const nlohmann::json& json, const std::string& key, int* leaves) {
  if (json.is_object()) {
    nlohmann::json changed = nlohmann::json::object();
    for (const auto& [name, value] : json.items()) {
      changed[name] = ChangeEveryLeaf(value, name, leaves);
    }
    return changed;
  }
  if (json.is_array()) {
    nlohmann::json changed = nlohmann::json::array();
    for (const nlohmann::json& value : json) changed.push_back(ChangeEveryLeaf(value, key, leaves));
    return changed;
  }
  ++*leaves;
  if (const auto name = kOtherEnumName.find(key); name != kOtherEnumName.end()) return name->second;
  if (json.is_boolean()) return !json.get<bool>();
  if (json.is_number_unsigned()) return json.get<uint64_t>() + 1;
  if (json.is_number_integer()) return json.get<int64_t>() + 1;
  if (json.is_number_float()) return json.get<double>() * 1.5 + 0.25;
  if (json.is_string()) return json.get<std::string>() + "-changed";
  ADD_FAILURE() << key << " holds " << json.dump() << ", which this test cannot change";
  return json;
}

template <typename Options>
class OptionsJson : public ::testing::Test {};

using AllOptions =
    ::testing::Types<capture::SourceOptions, capture::KeyframeSamplerOptions, slam::FeatureOptions,
                     slam::MatchOptions, slam::RegistrationOptions, slam::PoseGraphOptions,
                     slam::VocabularyOptions, slam::DenseAlignmentOptions, slam::TrackerOptions,
                     slam::MapperOptions, slam::VladOptions, store::ModelOptions,
                     store::PlyExportOptions, mapping::TrackStageOptions,
                     mapping::MapViewFeedOptions, mapping::MappingOptions, identify::LocatorOptions,
                     identify::PixelLabelOptions, identify::LabelViewOptions,
                     cli::LocateServerOptions, cli::LabelServiceOptions>;
TYPED_TEST_SUITE(OptionsJson, AllOptions);

TYPED_TEST(OptionsJson, EveryFieldReadsBackWhatWasWritten) {
  const nlohmann::json defaults = TypeParam();
  int leaves = 0;
  const nlohmann::json changed = ChangeEveryLeaf(defaults, "", &leaves);
  ASSERT_GT(leaves, 0);
  ASSERT_NE(changed, defaults);
  TypeParam options;
  from_json(changed, options);
  EXPECT_EQ(nlohmann::json(options), changed);
}

TYPED_TEST(OptionsJson, AnEmptyObjectLeavesTheDefaults) {
  TypeParam options;
  from_json(nlohmann::json::object(), options);
  EXPECT_EQ(nlohmann::json(options), nlohmann::json(TypeParam()));
}

TEST(MappingOptionsJson, NestedOptionsAreReadIntoTheirOwnStruct) {
  mapping::MappingOptions options;
  from_json(nlohmann::json::parse(R"({"sampler": {"rate_hz": 2.5},
                                      "mapper": {"pose_graph": {"max_iterations": 7},
                                                 "features": {"type": "sift"}},
                                      "view": {"world_up": [0, 0, 1], "choice": "preview"}})"),
            options);
  EXPECT_EQ(options.sampler.rate_hz, 2.5);
  EXPECT_EQ(options.mapper.pose_graph.max_iterations, 7);
  EXPECT_EQ(options.mapper.features.type, slam::FeatureOptions::Type::kSift);
  EXPECT_EQ(options.view.world_up, Eigen::Vector3d::UnitZ());
  EXPECT_EQ(options.view.choice, mapping::ViewChoice::kPreview);
  // What the struct sets apart from its members' defaults survives a partial config.
  EXPECT_EQ(options.mapper.pose_graph.odometry_loss_scale,
            mapping::MappingOptions().mapper.pose_graph.odometry_loss_scale);
  EXPECT_EQ(options.mapper.loop_candidates, mapping::MappingOptions().mapper.loop_candidates);
}

TEST(LocateServerOptionsJson, TheServerOwnsTheLabelServicesEditability) {
  const nlohmann::json json = cli::LocateServerOptions();
  EXPECT_FALSE(json.contains("read_only_reason"));
  EXPECT_FALSE(json["labels"].contains("editable"));
  EXPECT_FALSE(json["labels"].contains("read_only_reason"));
  cli::LocateServerOptions options;
  EXPECT_THROW(from_json(nlohmann::json::parse(R"({"labels": {"editable": false}})"), options),
               OptionsJsonError);
}

}  // namespace
}  // namespace sightmap
