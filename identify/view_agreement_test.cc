#include "identify/view_agreement.h"

#include <gtest/gtest.h>

#include "core/check.h"
#include "identify/view_agreement_testing.h"

namespace sightmap::identify {
namespace {

using testing::PoseAt;

class ViewAgreementTest : public ::testing::Test {
 protected:
  void SetUp() override {
    keyframe_camera_ = Intrinsics::FromPinhole(640, 480, 525.0, 525.0, 319.5, 239.5);
    photo_camera_ = Intrinsics::FromPinhole(1280, 960, 1000.0, 1000.0, 639.5, 479.5);
    world_from_keyframe_ = PoseAt({0, 0, 0}, 0);
    world_from_photo_ = PoseAt({0.3, -0.1, 0.4}, 10);
    cv::Mat grey;
    cv::Mat depth;
    wall_.Render(world_from_keyframe_, keyframe_camera_, &grey, &depth);
    thumbnail_ = MakeThumbnail(grey, depth, keyframe_camera_, options_);
    cv::Mat photo_depth;
    wall_.Render(world_from_photo_, photo_camera_, &photo_, &photo_depth);
  }

  ViewAgreement Measure(const cv::Mat& photo, const Eigen::Isometry3d& world_from_photo) const {
    return MeasureViewAgreement(AgreementImage(photo, options_), photo_camera_, world_from_photo,
                                thumbnail_, world_from_keyframe_, options_);
  }

  testing::TexturedWall wall_;
  ViewAgreementOptions options_;
  Intrinsics keyframe_camera_;
  Intrinsics photo_camera_;
  Eigen::Isometry3d world_from_keyframe_;
  Eigen::Isometry3d world_from_photo_;
  KeyframeThumbnail thumbnail_;
  cv::Mat photo_;
};

TEST_F(ViewAgreementTest, TheRightPoseLinesUpAndAPoseOffByHalfAMetreDoesNot) {
  const ViewAgreement right = Measure(photo_, world_from_photo_);
  ASSERT_TRUE(right.judged);
  EXPECT_GT(right.global_ncc, 0.9);
  EXPECT_GT(right.cell_median_ncc, 0.8);
  EXPECT_GE(right.cells, 40);  // most of the 8x8 grid sees the wall
  EXPECT_GT(right.samples, 10000);

  const ViewAgreement off = Measure(photo_, world_from_photo_ * PoseAt({0.5, 0, 0}, 0));
  ASSERT_TRUE(off.judged);
  EXPECT_LT(off.Score(), 0.35) << off.global_ncc << " " << off.cell_median_ncc;
  // Turned 3 degrees: 16 cm across the wall at 3 m, no longer the same view either.
  EXPECT_LT(Measure(photo_, world_from_photo_ * PoseAt({0, 0, 0}, 3)).Score(), 0.5);
}

TEST_F(ViewAgreementTest, ThePhonesExposureDoesNotMatter) {
  cv::Mat darker;
  photo_.convertTo(darker, -1, 0.5, 40.0);
  const double score = Measure(photo_, world_from_photo_).Score();
  EXPECT_NEAR(Measure(darker, world_from_photo_).Score(), score, 0.03);
}

TEST_F(ViewAgreementTest, APoseThatDoesNotSeeTheKeyframesViewIsNotJudged) {
  // Turned round: the wall is behind the photo.
  const ViewAgreement away = Measure(photo_, world_from_photo_ * PoseAt({0, 0, 0}, 180));
  EXPECT_FALSE(away.judged);
  EXPECT_EQ(away.samples, 0);
  EXPECT_DOUBLE_EQ(away.Score(), 0.0);
  // A blank photo: no cell varies enough to correlate.
  const ViewAgreement blank =
      Measure(cv::Mat(960, 1280, CV_8UC1, cv::Scalar(90)), world_from_photo_);
  EXPECT_FALSE(blank.judged);
  EXPECT_GT(blank.samples, 10000);
  EXPECT_EQ(blank.cells, 0);
}

TEST_F(ViewAgreementTest, AKeyframePixelBehindANearerOneIsNotCompared) {
  // A keyframe seeing the wall whose left half is a board 1 m nearer, textured as the wall behind
  // it; a photo from 1.2 m to the left, turned right, sees the board cover part of the wall the
  // keyframe saw beside it. The hidden wall pixels land where the board is: dropped, the rest still
  // agree.
  cv::Mat grey;
  cv::Mat depth;
  wall_.Render(world_from_keyframe_, keyframe_camera_, &grey, &depth);
  const cv::Mat board = depth(cv::Rect(0, 0, 320, 480));
  board -= 1000;
  const KeyframeThumbnail with_board = MakeThumbnail(grey, depth, keyframe_camera_, options_);
  // The photo of the same scene: each keyframe pixel placed in 3D and drawn nearest first.
  const Eigen::Isometry3d world_from_photo = PoseAt({-1.2, 0, 0.2}, 20);
  const Intrinsics small = photo_camera_.Scaled(320, 240);
  cv::Mat photo(240, 320, CV_8UC1, cv::Scalar(0));
  cv::Mat nearest(240, 320, CV_32F, cv::Scalar(1e9));
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      const double z = 1e-3 * depth.at<uint16_t>(v, u);
      if (z <= 0.0) continue;
      const Eigen::Vector3d p =
          world_from_photo.inverse() * world_from_keyframe_ * keyframe_camera_.Unproject(u, v, z);
      if (p.z() <= 0.1) continue;
      const Eigen::Vector2d uv = small.Project(p);
      const int x = static_cast<int>(std::lround(uv.x()));
      const int y = static_cast<int>(std::lround(uv.y()));
      if (x < 0 || y < 0 || x >= 320 || y >= 240 || p.z() >= nearest.at<float>(y, x)) continue;
      nearest.at<float>(y, x) = static_cast<float>(p.z());
      photo.at<uint8_t>(y, x) = grey.at<uint8_t>(v, u);
    }
  }
  cv::Mat full;
  cv::resize(photo, full, cv::Size(1280, 960), 0, 0, cv::INTER_NEAREST);
  const cv::Mat image = AgreementImage(full, options_);
  const ViewAgreement with_zbuffer = MeasureViewAgreement(
      image, photo_camera_, world_from_photo, with_board, world_from_keyframe_, options_);
  ViewAgreementOptions without = options_;
  without.occlusion_margin_ratio = 100.0;  // every pixel kept, hidden or not
  const ViewAgreement without_zbuffer = MeasureViewAgreement(
      image, photo_camera_, world_from_photo, with_board, world_from_keyframe_, without);
  ASSERT_TRUE(with_zbuffer.judged && without_zbuffer.judged);
  EXPECT_LT(with_zbuffer.samples, without_zbuffer.samples);
  EXPECT_GT(with_zbuffer.global_ncc, without_zbuffer.global_ncc + 0.05)
      << with_zbuffer.global_ncc << " " << without_zbuffer.global_ncc;
}

TEST_F(ViewAgreementTest, AKeyframeThatSawTheFurnitureHidesWhatAnotherSawPastIt) {
  // A board stands 1.2 m in front of the wall. The photo, from 3 m, sees it cover a third of the
  // wall; keyframe A stood between the board and the wall and saw only the wall behind it;
  // keyframe B stood near the photo and saw both.
  const testing::WallBehindBoard scene;
  const Eigen::Isometry3d world_from_photo = PoseAt({0, 0, 0}, 0);
  cv::Mat photo;
  cv::Mat photo_depth;
  scene.Render(world_from_photo, photo_camera_, &photo, &photo_depth);
  const auto thumbnail_from = [&](const Eigen::Isometry3d& world_from_keyframe) {
    cv::Mat grey;
    cv::Mat depth;
    scene.Render(world_from_keyframe, keyframe_camera_, &grey, &depth);
    return MakeThumbnail(grey, depth, keyframe_camera_, options_);
  };
  const Eigen::Isometry3d world_from_a = PoseAt({-0.2, 0, 2.2}, 0);
  const Eigen::Isometry3d world_from_b = PoseAt({0.3, 0.1, 0.3}, -5);
  const KeyframeThumbnail a = thumbnail_from(world_from_a);
  const KeyframeThumbnail b = thumbnail_from(world_from_b);
  const cv::Mat image = AgreementImage(photo, options_);

  // A alone compares the wall with the board the photo shows in front of it.
  const ViewAgreement a_alone =
      MeasureViewAgreement(image, photo_camera_, world_from_photo, a, world_from_a, options_);
  ASSERT_TRUE(a_alone.judged);
  EXPECT_LT(a_alone.Score(), 0.4) << a_alone.global_ncc << " " << a_alone.cell_median_ncc;
  // With B, B's board is nearer where A's wall pixels land: those are dropped, the rest agree.
  const std::vector<PlacedThumbnail> both = {{&a, world_from_a}, {&b, world_from_b}};
  const ViewAgreement together =
      MeasureViewAgreement(image, photo_camera_, world_from_photo, both, options_);
  ASSERT_TRUE(together.judged);
  EXPECT_GT(together.Score(), 0.8) << together.global_ncc << " " << together.cell_median_ncc;
  // One keyframe in the list is the single-keyframe check.
  const ViewAgreement a_listed =
      MeasureViewAgreement(image, photo_camera_, world_from_photo, {{&a, world_from_a}}, options_);
  EXPECT_EQ(a_listed.samples, a_alone.samples);
  EXPECT_DOUBLE_EQ(a_listed.Score(), a_alone.Score());
  // Together they still refuse a pose half a metre off.
  const ViewAgreement off = MeasureViewAgreement(
      image, photo_camera_, world_from_photo * PoseAt({0.5, 0, 0}, 0), both, options_);
  ASSERT_TRUE(off.judged);
  EXPECT_LT(off.Score(), 0.35) << off.global_ncc << " " << off.cell_median_ncc;
}

TEST(MakeThumbnailTest, AreaAveragedGreyAndDepthSampledNotAveraged) {
  const Intrinsics camera = Intrinsics::FromPinhole(640, 480, 525.0, 525.0, 319.5, 239.5);
  cv::Mat color(480, 640, CV_8UC3, cv::Scalar(10, 20, 30));
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(1000));
  // A depth edge every 3 px: a 4 px average would mix the two surfaces.
  for (int u = 0; u < 640; u += 3) depth.col(u).setTo(3000);
  const ViewAgreementOptions options;  // 160 px wide
  const KeyframeThumbnail thumbnail = MakeThumbnail(color, depth, camera, options);
  EXPECT_EQ(thumbnail.grey.size(), cv::Size(160, 120));
  EXPECT_EQ(thumbnail.depth_mm.size(), cv::Size(160, 120));
  EXPECT_EQ(thumbnail.intrinsics.width, 160);
  EXPECT_DOUBLE_EQ(thumbnail.intrinsics.fx, 525.0 / 4);
  EXPECT_EQ(thumbnail.Bytes(), 160u * 120u * 3u);
  for (int u = 0; u < 160; ++u) {
    const uint16_t d = thumbnail.depth_mm.at<uint16_t>(60, u);
    EXPECT_TRUE(d == 1000 || d == 3000) << d;
  }
  EXPECT_EQ(thumbnail.grey.at<uint8_t>(60, 80), 22);  // BGR (10, 20, 30) in grey
  EXPECT_THROW(MakeThumbnail(color, depth(cv::Rect(0, 0, 320, 240)), camera, options),
               InvalidArgument);
  EXPECT_THROW(MakeThumbnail(cv::Mat(), depth, camera, options), InvalidArgument);
}

TEST(ViewAgreementOptionsTest, CheckRefusesWhatCannotWork) {
  ViewAgreementOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error));
  options.max_depth_m = options.min_depth_m;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("max_depth_m"), std::string::npos);
  options = ViewAgreementOptions();
  options.min_cells = 65;
  EXPECT_FALSE(options.Check(&error));
  options = ViewAgreementOptions();
  options.thumbnail_width_px = 8;
  EXPECT_FALSE(options.Check(&error));
}

}  // namespace
}  // namespace sightmap::identify
