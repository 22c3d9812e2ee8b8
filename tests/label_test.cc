// `sightmap label` end to end: the real binary on a real model file (add from a pixel and from a
// typed point, list --json, remove, imports, export), and its one-line errors and exit codes.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "store/label_files.h"
#include "store/model.h"
#include "store/synthetic_model.h"
#include "tests/command_runner.h"
#include "tests/test_data.h"

namespace sightmap {
namespace {

using testing::CommandResult;
using testing::ExpectOneLineError;
using testing::Sightmap;

// Two 160x120 keyframes facing the synthetic wall 2 m away, the second 0.1 m along x.
std::string MakeModel(const std::string& dir) {
  const std::string path = dir + "/model.db";
  store::Model model = store::Model::Open(path);
  store::SyntheticKeyframeOptions options;
  options.width = 160;
  options.height = 120;
  options.num_features = 10;
  const SessionId session = model.BeginSession({});
  for (int i = 0; i < 2; ++i) model.AddKeyframe(store::MakeSyntheticKeyframe(session, i, options));
  model.EndSession(session, store::SessionEnd::kFinished, 1);
  return path;
}

nlohmann::json ListJson(const std::string& model) {
  const CommandResult run = Sightmap("label list --model " + model + " --json");
  EXPECT_EQ(run.exit_code, 0) << run.err;
  return nlohmann::json::parse(run.out);
}

void ExpectPoint(const nlohmann::json& point, const Eigen::Vector3d& expected) {
  ASSERT_EQ(point.size(), 3u) << point;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(point[i].get<double>(), expected[i], 1e-9) << point;
}

TEST(LabelCommand, AddListRemoveExport) {
  const std::string dir = testing::MakeTempDir("label_cli_add");
  const std::string model = MakeModel(dir);
  const Intrinsics k = store::SyntheticIntrinsics(160, 120);

  CommandResult run =
      Sightmap("label add --model " + model + " --name lamp --keyframe 2 --pixel 30,40");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("created label 'lamp' (appliance)"), std::string::npos) << run.out;
  run = Sightmap("label add --model " + model + " --name lamp --type lamp --point=-1,2.5,3");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("added to label 'lamp' (lamp): point 2"), std::string::npos) << run.out;
  ASSERT_EQ(Sightmap("label add --model " + model + " --name tv --point 4,5,6").exit_code, 0);

  nlohmann::json list = ListJson(model);
  ASSERT_EQ(list.at("labels").size(), 2u) << list;
  const nlohmann::json& lamp = list["labels"][0];
  EXPECT_EQ(lamp.at("name"), "lamp");
  EXPECT_EQ(lamp.at("type"), "lamp");
  ASSERT_EQ(lamp.at("points").size(), 2u);
  // Keyframe 2 sits 0.1 m along world x; its depth is 2 m everywhere.
  ExpectPoint(lamp["points"][0], k.Unproject(30, 40, 2.0) + Eigen::Vector3d(0.1, 0, 0));
  ExpectPoint(lamp["points"][1], {-1, 2.5, 3});
  EXPECT_EQ(lamp.at("point_sources")[0].at("source"), "keyframe_pixel");
  EXPECT_EQ(lamp["point_sources"][0].at("keyframe"), 2);
  EXPECT_EQ(lamp["point_sources"][1].at("source"), "typed");
  EXPECT_EQ(list["labels"][1].at("name"), "tv");
  EXPECT_EQ(list["labels"][1].at("type"), "appliance");

  run = Sightmap("label list --model " + model);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("lamp (lamp), 2 point(s):"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("tv (appliance), 1 point(s): [4.000, 5.000, 6.000] m"), std::string::npos)
      << run.out;

  run = Sightmap("label export --model " + model + " --dir " + dir + "/labels");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(store::ReadPointList(dir + "/labels/lamp.txt").size(), 2u);

  run = Sightmap("label remove --model " + model + " --name lamp");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("removed label 'lamp' (2 point(s))"), std::string::npos) << run.out;
  list = ListJson(model);
  ASSERT_EQ(list.at("labels").size(), 1u);
  EXPECT_EQ(list["labels"][0].at("name"), "tv");
}

TEST(LabelCommand, ImportsASceneFileAndPointLists) {
  const std::string dir = testing::MakeTempDir("label_cli_import");
  const std::string model = MakeModel(dir);
  std::ofstream(dir + "/appliances.json") << R"({"scene": "office", "appliances": [
      {"id": 1, "name": "monitor_1", "type": "monitor", "points": [[1.5, 2, 0.75]]},
      {"id": 2, "name": "lamp_1", "type": "lamp", "points": [[0, 1, 1.2], [0, 1.1, 1.3]]}]})";
  CommandResult run =
      Sightmap("label import --model " + model + " --from-scene " + dir + "/appliances.json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("imported 2 label(s), 3 point(s)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("created   lamp_1, monitor_1"), std::string::npos) << run.out;
  nlohmann::json list = ListJson(model);
  ASSERT_EQ(list.at("labels").size(), 2u);
  EXPECT_EQ(list["labels"][0].at("name"), "lamp_1");
  EXPECT_EQ(list["labels"][0].at("type"), "lamp");
  ExpectPoint(list["labels"][0]["points"][1], {0, 1.1, 1.3});
  EXPECT_EQ(list["labels"][1].at("type"), "monitor");

  // Again: the same labels are replaced, and the output says so.
  run = Sightmap("label import --model " + model + " --from-scene " + dir + "/appliances.json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("replaced  lamp_1, monitor_1"), std::string::npos) << run.out;
  EXPECT_EQ(ListJson(model).at("labels").size(), 2u);

  // As a user would click them (identify::ClickedLabelPoint): the output counts the points placed
  // on a keyframe's surface and names the labels left where the file puts them.
  run = Sightmap("label import --model " + model + " --from-scene " + dir +
                 "/appliances.json --as-clicked");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find(" of 3 point(s) placed on a keyframe's surface"), std::string::npos)
      << run.out;

  std::ofstream(dir + "/printer.txt") << "1 2 3\n4 5 6\n";
  std::ofstream(dir + "/lamp_1.xyz") << "7 8 9\n";
  run = Sightmap("label import --model " + model + " " + dir + "/printer.txt " + dir +
                 "/lamp_1.xyz --type printer");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  list = ListJson(model);
  ASSERT_EQ(list.at("labels").size(), 3u);
  EXPECT_EQ(list["labels"][0].at("type"), "printer");  // lamp_1: a type given replaces it
  ExpectPoint(list["labels"][0]["points"][0], {7, 8, 9});
  EXPECT_EQ(list["labels"][2].at("name"), "printer");
  EXPECT_EQ(list["labels"][2].at("points").size(), 2u);
}

TEST(LabelCommand, ErrorsAreOneLineWithExitCodes) {
  const std::string dir = testing::MakeTempDir("label_cli_errors");
  const std::string model = MakeModel(dir);
  ASSERT_EQ(Sightmap("label add --model " + model + " --name tv --point 1,2,3").exit_code, 0);

  const std::string missing = dir + "/missing.db";
  ExpectOneLineError(Sightmap("label add --model " + missing + " --name x --point 1,2,3"), 1,
                     "does not exist");
  ExpectOneLineError(Sightmap("label list --model " + missing), 1, "does not exist");
  EXPECT_FALSE(std::filesystem::exists(missing));

  const std::string add = "label add --model " + model + " --name lamp ";
  ExpectOneLineError(Sightmap(add + "--keyframe 99 --pixel 10,10"), 1, "keyframe 99");
  ExpectOneLineError(Sightmap(add + "--keyframe 1 --pixel 10x10"), 2, "--pixel must be U,V");
  ExpectOneLineError(Sightmap(add + "--keyframe 1 --pixel 10,10,3"), 2, "--pixel must be U,V");
  ExpectOneLineError(Sightmap(add + "--point 1,2"), 2, "--point must be X,Y,Z");
  ExpectOneLineError(Sightmap(add + "--keyframe 1 --pixel 500,10"), 1, "outside keyframe 1");
  ExpectOneLineError(Sightmap(add), 2, "needs a point");
  ExpectOneLineError(Sightmap(add + "--pixel 10,10"), 2, "--keyframe");
  ExpectOneLineError(Sightmap(add + "--keyframe 1 --pixel 10,10 --point 1,2,3"), 2, "exclude");
  ExpectOneLineError(Sightmap("label remove --model " + model + " --name lamp"), 1,
                     "no label named 'lamp'");
  ExpectOneLineError(Sightmap("label import --model " + model), 2, "neither");
  ExpectOneLineError(Sightmap("label import --model " + model + " a.txt --from-scene b.json"), 2,
                     "both");
  ExpectOneLineError(Sightmap("label import --model " + model + " a.txt --as-clicked"), 2,
                     "--as-clicked applies to --from-scene");
  ExpectOneLineError(Sightmap("label import --model " + model + " " + dir + "/none.txt"), 1,
                     "cannot read point list");
  std::ofstream(dir + "/bad.json") << R"({"appliances": [{"name": "lamp", "points": [[1, 2]]}]})";
  ExpectOneLineError(
      Sightmap("label import --model " + model + " --from-scene " + dir + "/bad.json"), 1,
      "is not [x, y, z]");
  std::ofstream(dir + "/broken.json") << R"({"appliances": [)";
  ExpectOneLineError(
      Sightmap("label import --model " + model + " --from-scene " + dir + "/broken.json"), 1,
      "not valid JSON");
  ExpectOneLineError(Sightmap("label"), 2, "subcommand");

  // Nothing above changed the labels.
  const nlohmann::json list = ListJson(model);
  ASSERT_EQ(list.at("labels").size(), 1u);
  EXPECT_EQ(list["labels"][0].at("name"), "tv");
}

// Names a person would not mean, and coordinates no building has, are refused with the reason;
// an export that would collide writes nothing.
TEST(LabelCommand, BadNamesAndPointsAreRefusedAndExportIsAllOrNothing) {
  const std::string dir = testing::MakeTempDir("label_cli_names");
  const std::string model = MakeModel(dir);
  const std::string add = "label add --model " + model + " --point 1,2,3 --name ";
  ExpectOneLineError(Sightmap(add + "''"), 2, "a label needs a name");
  ExpectOneLineError(Sightmap(add + "'   '"), 2, "cannot be only spaces");
  ExpectOneLineError(Sightmap(add + "\"$(printf 'a\\nb')\""), 2, "control characters");
  ExpectOneLineError(Sightmap(add + "\"$(printf 'tab\\there')\""), 2, "'tab\\there'");
  ExpectOneLineError(Sightmap(add + "' lamp'"), 2, "start or end with a space");
  ExpectOneLineError(Sightmap(add + std::string(101, 'x')), 2, "limited to 100 bytes");
  ExpectOneLineError(Sightmap("label add --model " + model + " --name lamp --point 1e300,1,1"), 2,
                     "within 10000 m");
  ExpectOneLineError(Sightmap("label add --model " + model + " --name lamp --point nan,1,1"), 2,
                     "--point must be X,Y,Z");
  ExpectOneLineError(Sightmap("label add --model " + model +
                              " --name lamp --point 1,2,3 --type \"$(printf 'a\\nb')\""),
                     2, "label type");
  EXPECT_TRUE(ListJson(model).at("labels").empty());

  // a/b and a_b would both be a_b.txt: the export refuses before writing any file.
  ASSERT_EQ(Sightmap(add + "zebra").exit_code, 0);
  ASSERT_EQ(Sightmap(add + "a/b").exit_code, 0);
  ASSERT_EQ(Sightmap(add + "a_b").exit_code, 0);
  const std::string out = dir + "/labels";
  ExpectOneLineError(Sightmap("label export --model " + model + " --dir " + out), 1,
                     "nothing was written");
  EXPECT_FALSE(std::filesystem::exists(out + "/zebra.txt"));
  ExpectOneLineError(Sightmap("label export --model " + model + " --dir /proc/labels"), 1,
                     "cannot create --dir /proc/labels");
}

// A target the export cannot replace (a folder named like a label's file) fails the whole export
// with one line naming it: the files already there stay as they were, none is added, and no
// temporary is left behind. Once it is moved away, the export replaces the old files.
TEST(LabelCommand, AnExportBlockedByAFolderChangesNothing) {
  const std::string dir = testing::MakeTempDir("label_cli_export_blocked");
  const std::string model = MakeModel(dir);
  for (const char* name : {"lamp", "tv", "zebra"}) {
    ASSERT_EQ(Sightmap("label add --model " + model + " --point 1,2,3 --name " + name).exit_code,
              0);
  }
  const std::string out = dir + "/labels";
  std::filesystem::create_directories(out + "/tv.txt");
  std::ofstream(out + "/lamp.txt") << "9 9 9\n";
  ExpectOneLineError(Sightmap("label export --model " + model + " --dir " + out), 1,
                     out + "/tv.txt");
  EXPECT_EQ(testing::Slurp(out + "/lamp.txt"), "9 9 9\n");
  std::vector<std::string> left;
  for (const auto& entry : std::filesystem::directory_iterator(out)) {
    left.push_back(entry.path().filename().string());
  }
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"lamp.txt", "tv.txt"}));

  std::filesystem::remove(out + "/tv.txt");
  const CommandResult run = Sightmap("label export --model " + model + " --dir " + out);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(testing::Slurp(out + "/lamp.txt"), "1.000000 2.000000 3.000000\n");
  left.clear();
  for (const auto& entry : std::filesystem::directory_iterator(out)) {
    left.push_back(entry.path().filename().string());
  }
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"lamp.txt", "tv.txt", "zebra.txt"}));
}

}  // namespace
}  // namespace sightmap
