#include "slam/mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <set>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "slam/blind_bridge.h"
#include "slam/pose_graph_stages.h"

namespace sightmap::slam {
namespace {

using Clock = std::chrono::steady_clock;

// What a link's information gets on its diagonal before it is inverted: a covariance of 1e9 along
// a direction the link does not fix.
constexpr double kRidge = 1e-9;

void AddRegistrationTimes(const RegistrationTimes& times, MapperStageTimes* total) {
  total->matching_s += times.matching_s;
  total->ransac_s += times.ransac_s;
  total->verification_s += times.verification_s;
  ++total->registrations;
}

// How far a relative pose turns the camera's down axis (image y): about gravity a walker turns
// freely, away from it barely [deg].
double DownAxisTurnDeg(const Eigen::Isometry3d& target_from_source) {
  const double cosine = target_from_source.linear().col(1).y();
  return RadToDeg(std::acos(std::clamp(cosine, -1.0, 1.0)));
}

// The link a registration of keyframe `to` (the source) against keyframe `from` (the target) makes.
MapperLink RegisteredLink(int64_t from, int64_t to, const RegistrationResult& result,
                          LinkType type) {
  MapperLink link;
  link.from = from;
  link.to = to;
  link.to_in_from = result.target_from_source;
  link.information = result.information;
  link.type = type;
  link.inliers = result.inliers;
  return link;
}

Eigen::Matrix<double, 6, 6> FlooredInformation(const Eigen::Matrix<double, 6, 6>& information,
                                               const MapperOptions& options) {
  return slam::FlooredInformation(information, options.link_min_sigma_m,
                                  options.link_min_sigma_rad);
}

// A link's covariance from its information (singular directions lifted by a tiny ridge, which
// leaves them free for all practical purposes).
Eigen::Matrix<double, 6, 6> CovarianceOf(const Eigen::Matrix<double, 6, 6>& information) {
  return RidgedInverse(information, kRidge);
}

// Features handed in (restored or tracked) must be one consistent set.
void CheckFeatures(const Features& features, const char* what) {
  // The mapper registers by points: every keypoint has its slot, even where there is no depth.
  SIGHTMAP_CHECK(features.IsConsistent() && features.has_point.size() == features.size(),
                 what << "'s features are inconsistent");
}

}  // namespace

bool MapperOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (!CheckOrbFeatures(features, error) || !registration.Check(error) ||
      !vocabulary.Check(error) || !pose_graph.Check(error) || !manhattan.Check(error) ||
      !wall_ties.Check(error)) {
    return false;
  }
  if (wall_tie_rounds < 0) return fail("wall_tie_rounds must not be negative (0: off)");
  if (bridge_frame != "camera" && bridge_frame != "world") {
    return fail("bridge_frame must be \"camera\" or \"world\"");
  }
  if (!(manhattan_sigma_deg >= 0.0) || !std::isfinite(manhattan_sigma_deg) ||
      !(manhattan_max_deviation_deg > 0.0 && manhattan_max_deviation_deg < 45.0)) {
    return fail(
        "manhattan_sigma_deg must not be negative (0: off), manhattan_max_deviation_deg in "
        "(0, 45)");
  }
  if (odometry_window < 1) return fail("odometry_window must be at least 1");
  if (extra_odometry_links < 0) return fail("extra_odometry_links must not be negative");
  if (!(extra_link_max_disagreement_m > 0.0) || !(extra_link_max_disagreement_deg > 0.0)) {
    return fail("extra_link_max_disagreement_m and _deg must be positive");
  }
  if (!(blind_link_max_deviation_mps >= 0.0) || !(blind_link_max_deviation_dps >= 0.0) ||
      !(blind_link_slack_m >= 0.0) || !(blind_link_slack_deg >= 0.0)) {
    return fail(
        "blind_link_max_deviation_mps, _dps and blind_link_slack_m, _deg must not be negative");
  }
  if (!(bridged_sigma_factor >= 0.0) || !std::isfinite(bridged_sigma_factor)) {
    return fail("bridged_sigma_factor must be a finite number >= 0 (0 turns bridging off)");
  }
  if (!(bridge_min_blind_step_s >= 0.0)) return fail("bridge_min_blind_step_s must be >= 0");
  if (depth_downscale < 1) return fail("depth_downscale must be at least 1");
  if (vocabulary_training_keyframes < 1) {
    return fail("vocabulary_training_keyframes must be at least 1");
  }
  if (loop_exclude_recent < 1) return fail("loop_exclude_recent must be at least 1");
  if (loop_candidates < 0) return fail("loop_candidates must not be negative");
  if (loop_min_inliers < 0) return fail("loop_min_inliers must not be negative");
  if (loop_min_relative_score < 0.0) return fail("loop_min_relative_score must not be negative");
  if (loop_min_spacing < 0) return fail("loop_min_spacing must not be negative");
  if (!loop_axes.Check(error)) return false;
  if (final_retry_max_loops < 0) return fail("final_retry_max_loops must not be negative (0: off)");
  if (!(loop_max_axes_chi2 >= 0.0) || !(loop_axes_max_sigma_deg > 0.0)) {
    return fail("loop_max_axes_chi2 must not be negative (0: off), loop_axes_max_sigma_deg > 0");
  }
  if (!(loop_max_graph_chi2 >= 0.0) || !(loop_check_link_sigma_m >= 0.0) ||
      !(loop_check_link_sigma_rad >= 0.0) || !(loop_check_lever_m >= 0.0) ||
      !(loop_check_slack_m >= 0.0) || !(loop_check_slack_rad >= 0.0)) {
    return fail(
        "loop_max_graph_chi2 and the loop_check_* sigmas, lever and slacks must not be "
        "negative");
  }
  if (proximity_candidates < 0 || proximity_min_inliers < 0) {
    return fail("proximity_candidates and proximity_min_inliers must not be negative");
  }
  if (!(proximity_radius_m > 0.0) || !(proximity_max_angle_deg > 0.0) ||
      !(proximity_max_disagreement_m > 0.0) || !(proximity_max_disagreement_deg > 0.0)) {
    return fail("proximity_radius_m, _max_angle_deg and _max_disagreement_* must be positive");
  }
  if (local_loop_hops < 0) return fail("local_loop_hops must not be negative (0: never local)");
  if (!(local_loop_max_border_chi2_rise >= 0.0)) {
    return fail("local_loop_max_border_chi2_rise must not be negative");
  }
  if (!(join_max_disagreement_m > 0.0) || !(join_max_disagreement_rad > 0.0)) {
    return fail("join_max_disagreement_m and join_max_disagreement_rad must be positive");
  }
  if (!(walk_max_speed_mps > 0.0) || !(walk_max_turn_rate_dps > 0.0) || !(walk_slack_m >= 0.0) ||
      !(walk_slack_deg >= 0.0) || !(walk_max_gap_s >= 0.0)) {
    return fail(
        "walk_max_speed_mps and walk_max_turn_rate_dps must be positive, the slacks and "
        "walk_max_gap_s not negative");
  }
  if (!(walk_max_tilt_deg > 0.0) || walk_max_tilt_deg > 180.0) {
    return fail("walk_max_tilt_deg must be in (0, 180]");
  }
  if (!(link_min_sigma_m > 0.0) || !(link_min_sigma_rad > 0.0)) {
    return fail("link_min_sigma_m and link_min_sigma_rad must be positive");
  }
  if (!dense.Check(error)) return false;
  if (!(dense_max_correction_m > 0.0) || !(dense_max_correction_deg > 0.0)) {
    return fail("dense_max_correction_m and dense_max_correction_deg must be positive");
  }
  if (!(dense_fit_max_correction_m >= 0.0) || !(dense_fit_max_correction_deg >= 0.0) ||
      !(dense_fit_max_rms_ratio > 0.0) || !(dense_fit_max_intensity_ratio > 0.0)) {
    return fail(
        "dense_fit_max_correction_* must not be negative and the dense_fit_*_ratio "
        "must be positive");
  }
  if (!(dense_link_min_sigma_m > 0.0) || !(dense_link_min_sigma_rad > 0.0)) {
    return fail("dense_link_min_sigma_m and dense_link_min_sigma_rad must be positive");
  }
  return true;
}

Mapper::Mapper(const Intrinsics& camera, const MapperOptions& options)
    : camera_(camera), options_(options) {
  SIGHTMAP_CHECK_OPTIONS(options_);
  SIGHTMAP_CHECK_OPTIONS(camera_);
  SIGHTMAP_CHECK(camera_.width % options_.depth_downscale == 0 &&
                     camera_.height % options_.depth_downscale == 0,
                 "depth_downscale " << options_.depth_downscale << " does not divide the "
                                    << camera_.width << "x" << camera_.height << " image");
  if (options_.dense_refinement) aligner_ = std::make_unique<DenseAligner>(camera_, options_.dense);
}

Mapper::~Mapper() = default;

void Mapper::SetVocabulary(std::shared_ptr<const Vocabulary> vocabulary) {
  SIGHTMAP_CHECK(keyframes_.empty(), "the vocabulary must be set before the first keyframe");
  vocabulary_ = std::move(vocabulary);
  vocabulary_given_ = vocabulary_ != nullptr;
}

Mapper::Keyframe& Mapper::Get(int64_t id) {
  SIGHTMAP_CHECK(id >= 0 && static_cast<size_t>(id) < keyframes_.size(), "no keyframe " << id);
  return keyframes_[static_cast<size_t>(id)];
}

const Mapper::Keyframe& Mapper::Get(int64_t id) const {
  SIGHTMAP_CHECK(id >= 0 && static_cast<size_t>(id) < keyframes_.size(), "no keyframe " << id);
  return keyframes_[static_cast<size_t>(id)];
}

int Mapper::Root(int segment) const {
  while (segment_parent_[static_cast<size_t>(segment)] != segment) {
    segment = segment_parent_[static_cast<size_t>(segment)];
  }
  return segment;
}

int Mapper::NumLoopClosures() const {
  return static_cast<int>(std::count_if(links_.begin(), links_.end(), [](const MapperLink& link) {
    return link.active && (link.type == LinkType::kLoopClosure || link.type == LinkType::kUser);
  }));
}

bool Mapper::AgreesWithTrackedMotion(const Eigen::Isometry3d& registered,
                                     const Eigen::Isometry3d& tracked) const {
  return MotionWithin(tracked.inverse() * registered, options_.extra_link_max_disagreement_m,
                      options_.extra_link_max_disagreement_deg);
}

bool Mapper::WithinBlindMotion(const Eigen::Isometry3d& registered,
                               const Eigen::Isometry3d& predicted, double blind_s) const {
  return MotionWithin(
      predicted.inverse() * registered,
      options_.blind_link_max_deviation_mps * blind_s + options_.blind_link_slack_m,
      options_.blind_link_max_deviation_dps * blind_s + options_.blind_link_slack_deg);
}

int Mapper::NumPriorLinks() const {
  return static_cast<int>(std::count_if(links_.begin(), links_.end(), [](const MapperLink& link) {
    return link.type == LinkType::kPrior;
  }));
}

int Mapper::NumSegments() const {
  int roots = 0;
  for (size_t s = 0; s < segment_parent_.size(); ++s) {
    if (segment_parent_[s] == static_cast<int>(s)) ++roots;
  }
  return roots;
}

std::vector<StampedPose> Mapper::Trajectory() const {
  std::vector<StampedPose> poses;
  poses.reserve(keyframes_.size());
  for (const Keyframe& keyframe : keyframes_) {
    poses.push_back({keyframe.timestamp_ns, graph_.Pose(keyframe.id)});
  }
  return poses;
}

Eigen::Isometry3d Mapper::WorldFromCam(int64_t id) const {
  Get(id);
  return graph_.Pose(id);
}

int Mapper::SegmentOf(int64_t id) const { return Root(Get(id).segment); }

const Features& Mapper::FeaturesOf(int64_t id) const { return Get(id).features; }

RegistrationResult Mapper::Register(const Keyframe& source, const Keyframe& target,
                                    MapperStageTimes* times, const Eigen::Isometry3d* prior,
                                    bool require_dense) const {
  RegistrationResult result =
      RegisterRgbd(source.features, target.features, source.depth_small, target.depth_small,
                   camera_, options_.registration, prior);
  AddRegistrationTimes(result.times, times);
  if (!result.success) return result;
  const double tilt_deg = DownAxisTurnDeg(result.target_from_source);
  if (tilt_deg > options_.walk_max_tilt_deg) {
    result.success = false;
    result.failure = "turns the camera's down axis by " +
                     std::to_string(static_cast<int>(std::lround(tilt_deg))) +
                     " deg: a walker holds the camera upright";
    return result;
  }
  result.information = FlooredInformation(result.information, options_);
  const bool refined =
      RefineDensely(source, target, &result.target_from_source, &result.information, times,
                    /*odometry=*/!require_dense);
  if (require_dense && !refined && source.HasDense() && target.HasDense()) {
    result.success = false;
    result.failure = "dense alignment does not confirm the features' pose";
  }
  return result;
}

std::shared_ptr<DenseAligner::Frame> Mapper::Prepared(const Keyframe& keyframe) const {
  // The keyframe being inserted has the id keyframes_.size().
  const int64_t oldest_kept = static_cast<int64_t>(keyframes_.size()) - options_.odometry_window;
  if (keyframe.id < oldest_kept) {
    return aligner_->Prepare(keyframe.dense.empty() ? Unpack(keyframe.packed_dense)
                                                    : keyframe.dense);
  }
  auto found = prepared_.find(keyframe.id);
  if (found == prepared_.end()) {
    found = prepared_.emplace(keyframe.id, aligner_->Prepare(keyframe.dense)).first;
  }
  std::shared_ptr<DenseAligner::Frame> frame = found->second;
  while (!prepared_.empty() && prepared_.begin()->first < oldest_kept) {
    prepared_.erase(prepared_.begin());
  }
  return frame;
}

void Mapper::PackOldDenseImages() {
  // Keyframes before the window are aligned only as loop candidates, a few times in a walk.
  const int64_t oldest_kept = static_cast<int64_t>(keyframes_.size()) - options_.odometry_window;
  for (int64_t id = oldest_kept - 1; id >= 0; --id) {
    Keyframe& keyframe = keyframes_[static_cast<size_t>(id)];
    if (keyframe.dense.empty()) break;
    keyframe.packed_dense = Pack(keyframe.dense);
    keyframe.dense = DenseImage();
  }
}

bool Mapper::RefineDensely(const Keyframe& source, const Keyframe& target,
                           Eigen::Isometry3d* target_from_source,
                           Eigen::Matrix<double, 6, 6>* information, MapperStageTimes* times,
                           bool odometry) const {
  if (!aligner_ || !source.HasDense() || !target.HasDense()) return false;
  const Clock::time_point start = Clock::now();
  const std::shared_ptr<DenseAligner::Frame> source_frame = Prepared(source);
  const std::shared_ptr<DenseAligner::Frame> target_frame = Prepared(target);
  const DenseAlignment aligned = aligner_->Align(*source_frame, *target_frame, *target_from_source);
  bool accepted = false;
  if (aligned.success) {
    const Eigen::Isometry3d correction = target_from_source->inverse() * aligned.target_from_source;
    accepted = MotionWithin(correction, options_.dense_max_correction_m,
                            options_.dense_max_correction_deg) ||
               (odometry &&
                MotionWithin(correction, options_.dense_fit_max_correction_m,
                             options_.dense_fit_max_correction_deg) &&
                FitsBetter(aligner_->Fit(*source_frame, *target_frame, aligned.target_from_source),
                           aligner_->Fit(*source_frame, *target_frame, *target_from_source)));
  }
  times->dense_s += SecondsSince(start);
  if (!accepted) return false;
  *target_from_source = aligned.target_from_source;
  *information = FlooredInformation(aligned.information, options_.dense_link_min_sigma_m,
                                    options_.dense_link_min_sigma_rad);
  return true;
}

bool Mapper::FitsBetter(const DenseFit& refined, const DenseFit& start) const {
  return refined.pair_fraction >= start.pair_fraction &&
         refined.normalised_rms <= options_.dense_fit_max_rms_ratio * start.normalised_rms &&
         refined.intensity_rms <= options_.dense_fit_max_intensity_ratio * start.intensity_rms;
}

void Mapper::AddLink(const MapperLink& link, KeyframeReport* report) {
  PoseGraphEdge edge;
  edge.from = link.from;
  edge.to = link.to;
  edge.to_in_from = link.to_in_from;
  edge.information = link.information;
  edge.type = link.type;
  // Links and graph edges are added together only here, so a link's index is its edge's index.
  const size_t index = graph_.AddEdge(edge);
  SIGHTMAP_CHECK(index == links_.size(), "pose graph edges and mapper links out of step");
  links_.push_back(link);
  report->new_links.push_back(link);
}

void Mapper::AddGraphPose(int64_t id, const Eigen::Isometry3d& world_from_cam) {
  graph_.AddPose(id, world_from_cam);
  // The map's first keyframe defines its world frame (anchored to a source's ground truth, or a
  // stored map's): held in every optimisation. A local optimisation around a loop that reaches
  // it would otherwise move it, and with it the whole map's frame, to agree with the drifted end
  // of the loop (measured: 2.5 m and 16 deg on the survey walk's lap back to its start).
  if (keyframes_.empty()) graph_.SetFixed(id, true);
}

ManhattanOptions Mapper::ManhattanOptionsFor(const cv::Mat& depth_mm) const {
  // A restored or tracked keyframe's small depth holds the same samples on a coarser grid.
  ManhattanOptions options = options_.manhattan;
  options.grid_step_px = std::max(1, options.grid_step_px * depth_mm.cols / camera_.width);
  return options;
}

void Mapper::MeasureAxesAndWalls(const cv::Mat& depth_mm, Keyframe* keyframe) const {
  keyframe->cam_from_axes.reset();
  keyframe->planes.clear();
  if (!(options_.manhattan_sigma_deg > 0.0)) return;
  const ManhattanOptions options = ManhattanOptionsFor(depth_mm);
  const Intrinsics camera = camera_.Scaled(depth_mm.cols, depth_mm.rows);
  // One set of patches serves the axes and the walls.
  const std::vector<PlanePatch> patches = PlanePatches(depth_mm, camera, options);
  const std::optional<ManhattanFit> fit = FitManhattanFrame(patches, options);
  if (!fit) return;
  keyframe->cam_from_axes = fit->cam_from_manhattan;
  if (options_.wall_tie_rounds > 0) {
    keyframe->planes = FindAxisPlanes(patches, fit->cam_from_manhattan, options_.wall_ties);
  }
}

void Mapper::AddRotationPrior(const Keyframe& keyframe) {
  if (!keyframe.cam_from_axes) return;
  RotationPrior prior;
  prior.cam_from_axes = *keyframe.cam_from_axes;
  prior.sigma_rad = DegToRad(options_.manhattan_sigma_deg);
  prior.max_deviation_rad = DegToRad(options_.manhattan_max_deviation_deg);
  graph_.SetRotationPrior(keyframe.id, prior);
}

void Mapper::SetFirstPose(const Eigen::Isometry3d& world_from_cam) {
  SIGHTMAP_CHECK(keyframes_.empty(), "the first pose is set before the first keyframe");
  first_world_from_cam_ = Orthonormalised(world_from_cam);
}

Mapper::Keyframe Mapper::MakeKeyframe(TimestampNs timestamp_ns, const cv::Mat& color,
                                      const cv::Mat& depth_mm, KeyframeReport* report) const {
  SIGHTMAP_CHECK(
      color.type() == CV_8UC3 && color.cols == camera_.width && color.rows == camera_.height,
      "a keyframe's colour must be 8-bit BGR of " << camera_.width << "x" << camera_.height);
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1 && depth_mm.size() == color.size(),
                 "a keyframe's depth must be 16-bit [mm] of the colour image's size");
  Keyframe keyframe;
  keyframe.id = static_cast<int64_t>(keyframes_.size());
  keyframe.timestamp_ns = timestamp_ns;
  keyframe.walk = walk_;
  const Clock::time_point stage = Clock::now();
  keyframe.features = ExtractFeatures(color, depth_mm, camera_, options_.features);
  cv::resize(
      depth_mm, keyframe.depth_small,
      cv::Size(camera_.width / options_.depth_downscale, camera_.height / options_.depth_downscale),
      0.0, 0.0, cv::INTER_NEAREST);
  if (options_.dense_refinement) {
    keyframe.dense = MakeDenseImage(color, depth_mm, camera_, options_.dense);
  }
  report->times.features_s = SecondsSince(stage);
  report->id = keyframe.id;
  report->features = static_cast<int>(keyframe.features.size());
  return keyframe;
}

KeyframeReport Mapper::AddKeyframeAtPose(TimestampNs timestamp_ns, const cv::Mat& color,
                                         const cv::Mat& depth_mm,
                                         const Eigen::Isometry3d& world_from_cam) {
  const Clock::time_point start = Clock::now();
  KeyframeReport report;
  Keyframe keyframe = MakeKeyframe(timestamp_ns, color, depth_mm, &report);
  keyframe.dense = DenseImage();  // a known pose needs no refinement
  const Eigen::Isometry3d pose = Orthonormalised(world_from_cam);
  std::optional<MapperLink> link;
  if (keyframes_.empty()) {
    segment_parent_.push_back(0);
  } else {
    const Keyframe& last = keyframes_.back();
    keyframe.segment = last.segment;
    MapperLink known;
    known.from = last.id;
    known.to = keyframe.id;
    known.to_in_from = graph_.Pose(last.id).inverse() * pose;
    // Exact, so as stiff as the floor allows: an optimisation after a later link changes nothing.
    known.information =
        FlooredInformation(Eigen::Matrix<double, 6, 6>::Identity() * 1e12, options_);
    known.type = LinkType::kOdometry;
    link = known;
  }
  start_new_segment_ = false;
  AddGraphPose(keyframe.id, pose);
  if (link) AddLink(*link, &report);
  keyframes_.push_back(std::move(keyframe));
  if (!vocabulary_ &&
      static_cast<int>(keyframes_.size()) >= options_.vocabulary_training_keyframes) {
    TrainVocabulary(&report.times);
  } else if (vocabulary_) {
    const Clock::time_point stage = Clock::now();
    IndexKeyframe(keyframes_.back());
    report.times.place_recognition_s += SecondsSince(stage);
  }
  state_ = TrackingState::kTracking;
  report.segment = Root(keyframes_.back().segment);
  report.state = state_;
  report.world_from_cam = graph_.Pose(report.id);
  report.times.total_s = SecondsSince(start);
  return report;
}

KeyframeReport Mapper::AddKeyframe(TimestampNs timestamp_ns, const cv::Mat& color,
                                   const cv::Mat& depth_mm) {
  const Clock::time_point start = Clock::now();
  KeyframeReport report;
  Keyframe keyframe = MakeKeyframe(timestamp_ns, color, depth_mm, &report);
  // Only keyframes the graph places need the axes: a known pose is never optimised.
  const Clock::time_point axes_stage = Clock::now();
  MeasureAxesAndWalls(depth_mm, &keyframe);
  report.times.features_s += SecondsSince(axes_stage);
  Insert(std::move(keyframe), nullptr, &report);
  report.times.total_s = SecondsSince(start);
  return report;
}

KeyframeReport Mapper::AddTrackedKeyframe(TrackedKeyframe tracked) {
  const Clock::time_point start = Clock::now();
  const cv::Size small(camera_.width / options_.depth_downscale,
                       camera_.height / options_.depth_downscale);
  SIGHTMAP_CHECK(tracked.depth_small.type() == CV_16UC1 && tracked.depth_small.size() == small,
                 "a tracked keyframe's depth must be 16-bit [mm] of 1/" << options_.depth_downscale
                                                                        << " the camera's size");
  CheckFeatures(tracked.features, "a tracked keyframe");
  KeyframeReport report;
  Keyframe keyframe;
  keyframe.id = static_cast<int64_t>(keyframes_.size());
  keyframe.timestamp_ns = tracked.frame.timestamp_ns;
  keyframe.walk = walk_;
  keyframe.features = std::move(tracked.features);
  keyframe.depth_small = tracked.depth_small;
  if (options_.dense_refinement) {
    const Clock::time_point stage = Clock::now();
    keyframe.dense =
        MakeDenseImage(tracked.frame.color, tracked.frame.depth, camera_, options_.dense);
    report.times.dense_s += SecondsSince(stage);
  }
  const Clock::time_point axes_stage = Clock::now();
  MeasureAxesAndWalls(tracked.frame.depth.empty() ? tracked.depth_small : tracked.frame.depth,
                      &keyframe);
  report.times.features_s += SecondsSince(axes_stage);
  report.id = keyframe.id;
  report.features = static_cast<int>(keyframe.features.size());
  const std::optional<KeyframeMotion>& motion = tracked.motion;
  const bool continues = motion && !keyframes_.empty() && !start_new_segment_;
  Insert(std::move(keyframe), continues ? &*motion : nullptr, &report);
  report.times.total_s = SecondsSince(start);
  return report;
}

std::optional<KeyframeMotion> Mapper::RefinedMotion(const Keyframe& keyframe,
                                                    const KeyframeMotion* tracked_motion,
                                                    MapperStageTimes* times, bool* refined) const {
  *refined = false;
  if (!tracked_motion) return std::nullopt;
  // The tracker's motion is refined like a registration when features registered it. Motions
  // chained through dense steps or guessed by the motion model are not: they come from views
  // without features (a bare wall), where alignment started 12 degrees off converges within 2
  // degrees of its start (measured on the simulated walk) and would claim millimetres for it.
  KeyframeMotion motion = *tracked_motion;
  if (tracked_motion->source == MotionSource::kRegistered && !keyframes_.empty()) {
    *refined = RefineDensely(keyframe, keyframes_.back(), &motion.previous_from_cam,
                             &motion.information, times, /*odometry=*/true);
  }
  return motion;
}

Eigen::Isometry3d Mapper::PredictPose(const KeyframeMotion* motion) const {
  const Keyframe& last = keyframes_.back();
  const Eigen::Isometry3d world_from_last = graph_.Pose(last.id);
  if (motion) return Orthonormalised(world_from_last * motion->previous_from_cam);
  // Without a tracked motion, the last motion again (a walker keeps turning and walking for a
  // few seconds), when the two keyframes before are of one segment.
  if (last.id > 0 &&
      Root(keyframes_[static_cast<size_t>(last.id - 1)].segment) == Root(last.segment)) {
    return world_from_last * (graph_.Pose(last.id - 1).inverse() * world_from_last);
  }
  return world_from_last;
}

std::vector<MapperLink> Mapper::RegisterOdometry(const Keyframe& keyframe,
                                                 const KeyframeMotion* motion,
                                                 const Eigen::Isometry3d& predicted,
                                                 KeyframeReport* report) const {
  // The newest keyframes, newest first. They may lie in an older segment than the last keyframe:
  // when one keyframe could not be registered (a bare wall filled the view), the next one often
  // registers to the keyframes before it and so continues their segment. A tracked keyframe is
  // linked to the last one already; its registrations start one further back.
  std::vector<MapperLink> odometry;
  const Keyframe& last = keyframes_.back();
  const int segment_root = Root(last.segment);
  const int64_t first_target = motion ? last.id - 1 : last.id;
  const int wanted_links = options_.extra_odometry_links + (motion ? 0 : 1);
  for (int64_t id = first_target; !start_new_segment_ && wanted_links > 0 && id >= 0 &&
                                  last.id - id < options_.odometry_window;
       --id) {
    const Keyframe& target = keyframes_[static_cast<size_t>(id)];
    const int target_root = Root(target.segment);
    const int64_t anchor = !odometry.empty() ? odometry[0].from : (motion ? last.id : -1);
    if (anchor >= 0 && target_root != Root(keyframes_[static_cast<size_t>(anchor)].segment)) {
      continue;  // links of one keyframe stay within one segment
    }
    // The prediction is in the last keyframe's segment frame: no prior for other segments.
    const Eigen::Isometry3d prior = graph_.Pose(target.id).inverse() * predicted;
    const RegistrationResult result =
        Register(keyframe, target, &report->times, target_root == segment_root ? &prior : nullptr,
                 /*require_dense=*/false);
    if (!result.success) {
      if (report->odometry_failure.empty()) {
        report->odometry_failure = "to keyframe " + std::to_string(id) + ": " + result.failure;
      }
      continue;
    }
    if (motion && motion->source != MotionSource::kPrior &&
        !AgreesWithTrackedMotion(graph_.Pose(target.id) * result.target_from_source, predicted)) {
      // An extra link is odometry and never switched off: one 40 degrees off (a repeated texture
      // registered across a second) bent a whole walk once the next loop was optimised.
      continue;
    }
    if (motion && motion->source == MotionSource::kPrior &&
        !WithinBlindMotion(graph_.Pose(target.id) * result.target_from_source, predicted,
                           motion->blind_s)) {
      if (report->odometry_failure.empty()) {
        report->odometry_failure = "to keyframe " + std::to_string(id) +
                                   ": further from the motion model than a walker goes";
      }
      continue;
    }
    odometry.push_back(RegisteredLink(target.id, keyframe.id, result, LinkType::kOdometry));
    if (static_cast<int>(odometry.size()) >= wanted_links) break;
  }
  return odometry;
}

MapperLink Mapper::TrackedMotionLink(int64_t id, const KeyframeMotion& motion, bool refined) const {
  MapperLink link;
  link.from = keyframes_.back().id;
  link.to = id;
  link.to_in_from = Orthonormalised(motion.previous_from_cam);
  link.information =
      refined ? motion.information : FlooredInformation(motion.information, options_);
  link.type = motion.source == MotionSource::kPrior ? LinkType::kPrior : LinkType::kOdometry;
  link.inliers = motion.inliers;
  return link;
}

Eigen::Isometry3d Mapper::PlaceKeyframe(const std::vector<MapperLink>& registered,
                                        const KeyframeMotion* motion,
                                        const Eigen::Isometry3d& predicted) const {
  // A motion the tracker measured places the keyframe; one only guessed (the motion model) yields
  // to a registration.
  if (motion && (registered.empty() || motion->source != MotionSource::kPrior)) return predicted;
  if (!registered.empty())
    return graph_.Pose(registered.front().from) * registered.front().to_in_from;
  return graph_.Pose(keyframes_.back().id);
}

void Mapper::AssignSegment(const std::vector<MapperLink>& odometry, const KeyframeMotion* motion,
                           Keyframe* keyframe, KeyframeReport* report) {
  keyframe->segment =
      odometry.empty() ? keyframes_.back().segment : Get(odometry.front().from).segment;
  if (odometry.empty() || start_new_segment_) {
    // Lost: a new segment, seeded where the camera was last.
    keyframe->segment = static_cast<int>(segment_parent_.size());
    segment_parent_.push_back(keyframe->segment);
  } else if (!motion || motion->source != MotionSource::kPrior) {
    report->odometry_failure.clear();
  }
}

bool Mapper::RecognisePlace(Keyframe& keyframe, KeyframeReport* report) {
  if (!vocabulary_) {
    if (static_cast<int>(keyframes_.size()) >= options_.vocabulary_training_keyframes) {
      TrainVocabulary(&report->times);
    }
    return false;
  }
  const bool relocalised = SearchPlaces(keyframe, report);
  if (!relocalised && !report->loop_closed) SearchNearby(keyframe, report);
  return relocalised;
}

void Mapper::Insert(Keyframe keyframe, const KeyframeMotion* tracked_motion,
                    KeyframeReport* report) {
  bool motion_refined = false;
  const std::optional<KeyframeMotion> refined_motion =
      RefinedMotion(keyframe, tracked_motion, &report->times, &motion_refined);
  const KeyframeMotion* motion = refined_motion ? &*refined_motion : nullptr;
  std::vector<MapperLink> odometry;
  Eigen::Isometry3d world_from_cam = first_world_from_cam_;
  if (!keyframes_.empty()) {
    const Eigen::Isometry3d predicted = PredictPose(motion);
    odometry = RegisterOdometry(keyframe, motion, predicted, report);
    world_from_cam = PlaceKeyframe(odometry, motion, predicted);
    if (motion) {
      odometry.insert(odometry.begin(), TrackedMotionLink(keyframe.id, *motion, motion_refined));
    }
    AssignSegment(odometry, motion, &keyframe, report);
  } else {
    segment_parent_.push_back(0);
  }
  if (start_new_segment_) report->odometry_failure = "a new segment was asked for";
  start_new_segment_ = false;
  AddGraphPose(keyframe.id, world_from_cam);
  AddRotationPrior(keyframe);
  // The tracked motion is the first of the links (TrackedMotionLink).
  if (motion) {
    keyframe.motion_link = static_cast<int64_t>(links_.size());
    keyframe.motion_source = motion->source;
  }
  for (const MapperLink& link : odometry) AddLink(link, report);
  if (motion && motion->source == MotionSource::kRegistered) {
    BridgeBlindRunBefore(keyframe, *motion, report);
  }
  keyframes_.push_back(std::move(keyframe));
  Keyframe& inserted = keyframes_.back();
  const bool relocalised = RecognisePlace(inserted, report);
  // Lost: this keyframe could not be registered to the last ones and starts a segment of its own
  // (NumSegments() says how many parts of the map are not joined yet). The first keyframe of a
  // map, and of a resumed session that is not relocalised at once, count as lost too.
  if (relocalised) {
    state_ = TrackingState::kRelocalised;
  } else if (!odometry.empty()) {
    state_ = TrackingState::kTracking;
  } else {
    state_ = keyframes_.size() == 1 ? TrackingState::kTracking : TrackingState::kLost;
  }

  report->segment = Root(inserted.segment);
  report->state = state_;
  report->world_from_cam = graph_.Pose(inserted.id);
  PackOldDenseImages();
}

void Mapper::BridgeBlindRunBefore(const Keyframe& keyframe, const KeyframeMotion& motion,
                                  KeyframeReport* report) {
  if (!(options_.bridged_sigma_factor > 0.0)) return;
  // The run, oldest first, back to the keyframe before it (`before`). Both sides must be
  // registered by features: a dense chain's motion errs by degrees before the bare wall that
  // blinds the frames after it (10 Hz hand-held seed 11, keyframe 114: 3 degrees), and a bridge
  // from it put the stretch beyond the run 11 cm off.
  std::vector<int64_t> run;
  int64_t before = keyframe.id - 1;
  for (; before >= 1; --before) {
    const Keyframe& candidate = Get(before);
    if (candidate.motion_link < 0 || candidate.walk != keyframe.walk) return;
    if (candidate.motion_source != MotionSource::kPrior) break;
    run.insert(run.begin(), before);
  }
  if (run.empty() || before < 1 || Get(before).motion_source != MotionSource::kRegistered) return;
  const auto seconds_to = [this, &keyframe](int64_t id) {
    const TimestampNs end_ns = id == keyframe.id ? keyframe.timestamp_ns : Get(id).timestamp_ns;
    return 1e-9 * static_cast<double>(end_ns - Get(id - 1).timestamp_ns);
  };
  std::vector<double> blind_dt_s;
  for (int64_t id : run) blind_dt_s.push_back(seconds_to(id));
  const TimedMotion measured_before{links_[static_cast<size_t>(Get(before).motion_link)].to_in_from,
                                    seconds_to(before)};
  const TimedMotion measured_after{motion.previous_from_cam, seconds_to(keyframe.id)};
  // A source's clock that stood still leaves no velocity to bridge with.
  const double shortest_step_s = *std::min_element(blind_dt_s.begin(), blind_dt_s.end());
  if (std::min({measured_before.dt_s, measured_after.dt_s, shortest_step_s}) <= 0.0 ||
      shortest_step_s < options_.bridge_min_blind_step_s) {
    return;
  }
  // A step whose both ends show the building's axes turns as the axes say (the naming nearest
  // the interpolated turn).
  std::vector<std::optional<Eigen::Matrix3d>> step_rotations(run.size());
  if (options_.bridge_rotations_from_axes) {
    const std::vector<Eigen::Isometry3d> interpolated =
        BridgeBlindRun(measured_before, blind_dt_s, measured_after);
    for (size_t i = 0; i < run.size(); ++i) {
      const Keyframe& from = Get(run[i] - 1);
      const Keyframe& to = Get(run[i]);
      if (!from.cam_from_axes || !to.cam_from_axes) continue;
      const auto [measured, deviation] = NearestManhattanRotation(
          *from.cam_from_axes, *to.cam_from_axes, interpolated[i].linear());
      if (deviation <= DegToRad(options_.manhattan_max_deviation_deg * 2.0)) {
        step_rotations[i] = measured;
      }
    }
  }
  const std::vector<Eigen::Isometry3d> bridged =
      BridgeBlindRun(measured_before, blind_dt_s, measured_after,
                     options_.bridge_frame == "world" ? BridgeFrame::kWorld : BridgeFrame::kCamera,
                     step_rotations);
  const double information_scale =
      1.0 / (options_.bridged_sigma_factor * options_.bridged_sigma_factor);
  for (size_t i = 0; i < run.size(); ++i) {
    const auto index = static_cast<size_t>(Get(run[i]).motion_link);
    MapperLink& link = links_[index];
    link.to_in_from = Orthonormalised(bridged[i]);
    link.information *= information_scale;
    graph_.SetEdgeMeasurement(index, link.to_in_from, link.information);
    report->revised_links.push_back(index);
  }
}

int64_t Mapper::RestoreKeyframe(TimestampNs timestamp_ns, Features features,
                                const cv::Mat& depth_mm, const Eigen::Isometry3d& world_from_cam,
                                const cv::Mat& color) {
  const cv::Size small(camera_.width / options_.depth_downscale,
                       camera_.height / options_.depth_downscale);
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1 &&
                     (depth_mm.size() == small ||
                      (depth_mm.cols == camera_.width && depth_mm.rows == camera_.height)),
                 "a restored keyframe's depth must be 16-bit [mm] of the camera's size or 1/"
                     << options_.depth_downscale << " of it");
  CheckFeatures(features, "a restored keyframe");
  Keyframe keyframe;
  keyframe.id = static_cast<int64_t>(keyframes_.size());
  keyframe.timestamp_ns = timestamp_ns;
  keyframe.features = std::move(features);
  if (depth_mm.size() == small) {
    keyframe.depth_small = depth_mm.clone();
  } else {
    cv::resize(depth_mm, keyframe.depth_small, small, 0.0, 0.0, cv::INTER_NEAREST);
  }
  if (options_.dense_refinement && !color.empty() && depth_mm.size() == color.size()) {
    keyframe.dense = MakeDenseImage(color, depth_mm, camera_, options_.dense);
  }
  MeasureAxesAndWalls(depth_mm, &keyframe);
  keyframe.segment = static_cast<int>(segment_parent_.size());
  segment_parent_.push_back(keyframe.segment);
  AddGraphPose(keyframe.id, world_from_cam);
  AddRotationPrior(keyframe);
  keyframes_.push_back(std::move(keyframe));
  PackOldDenseImages();
  if (vocabulary_) IndexKeyframe(keyframes_.back());
  // The next new keyframe cannot be registered to a stored one by odometry: the camera was off.
  StartNewSegment();
  return keyframes_.back().id;
}

void Mapper::RestoreLink(const MapperLink& link) {
  const int from_root = Root(Get(link.from).segment);
  const int to_root = Root(Get(link.to).segment);
  KeyframeReport ignored;
  AddLink(link, &ignored);
  if (!link.active) graph_.SetEdgeActive(links_.size() - 1, false);
  if (from_root != to_root) {
    segment_parent_[static_cast<size_t>(std::max(from_root, to_root))] =
        std::min(from_root, to_root);
  }
}

KeyframeReport Mapper::AddExternalLink(const MapperLink& link) {
  SIGHTMAP_CHECK(SegmentOf(link.from) == SegmentOf(link.to),
                 "an external link must join keyframes of one segment");
  KeyframeReport report;
  report.id = link.to;
  AddLink(link, &report);
  Optimise(link.to, &report);
  report.segment = SegmentOf(link.to);
  report.state = state_;
  report.world_from_cam = graph_.Pose(link.to);
  return report;
}

KeyframeReport Mapper::OptimiseWhole() {
  KeyframeReport report;
  if (keyframes_.empty()) return report;
  const std::vector<size_t> retried = RetryRejectedLoops();
  std::set<int> roots;
  for (const Keyframe& keyframe : keyframes_) {
    if (roots.insert(Root(keyframe.segment)).second) {
      Optimise(keyframe.id, &report, options_.seeded_final_solve);
    }
  }
  for (int round = 0; round < options_.wall_tie_rounds; ++round) {
    // Only within a segment: unjoined segments' poses are in frames of their own.
    std::vector<PlaneTie> ties;
    for (const auto& [root, sightings] : PlaneSightingsOfParts()) {
      const std::vector<PlaneTie> tied =
          TieWalls(sightings, graph_.WorldFromAxes(), options_.wall_ties);
      ties.insert(ties.end(), tied.begin(), tied.end());
    }
    graph_.SetPlaneTies(std::move(ties));
    if (graph_.NumPlaneTies() == 0) break;
    roots.clear();
    for (const Keyframe& keyframe : keyframes_) {
      if (roots.insert(Root(keyframe.segment)).second) Optimise(keyframe.id, &report, false);
    }
  }
  NetRetriedLoops(retried, &report);
  const Keyframe& newest = keyframes_.back();
  report.id = newest.id;
  report.segment = SegmentOf(newest.id);
  report.state = state_;
  report.world_from_cam = graph_.Pose(newest.id);
  return report;
}

std::vector<size_t> Mapper::RetryRejectedLoops() {
  std::vector<size_t> rejected;
  for (size_t i = 0; i < links_.size(); ++i) {
    if (!links_[i].active && links_[i].type == LinkType::kLoopClosure) rejected.push_back(i);
  }
  if (static_cast<int>(rejected.size()) > options_.final_retry_max_loops) return {};
  for (size_t i : rejected) {
    links_[i].active = true;
    graph_.SetEdgeActive(i, true);
  }
  return rejected;
}

void Mapper::NetRetriedLoops(const std::vector<size_t>& retried, KeyframeReport* report) const {
  // A retried loop switched off again was off before: no change to report.
  const std::set<size_t> retried_set(retried.begin(), retried.end());
  std::vector<size_t> rejected;
  for (size_t i : report->rejected_links) {
    if (retried_set.count(i) == 0) rejected.push_back(i);
  }
  report->rejected_links = std::move(rejected);
  report->links_rejected = static_cast<int>(report->rejected_links.size());
  for (size_t i : retried) {
    if (links_[i].active) report->reactivated_links.push_back(i);
  }
}

std::map<int, std::vector<PlaneSightings>> Mapper::PlaneSightingsOfParts() const {
  // Rigid parts: keyframes joined by active registered links (not the motion model's priors).
  std::map<int64_t, size_t> index_of;
  for (size_t i = 0; i < keyframes_.size(); ++i) index_of[keyframes_[i].id] = i;
  internal::Components parts(keyframes_.size());
  for (const MapperLink& link : links_) {
    if (link.type == LinkType::kPrior || !link.active) continue;
    parts.Join(index_of.at(link.from), index_of.at(link.to));
  }
  std::map<int, std::vector<PlaneSightings>> sightings;
  for (const Keyframe& keyframe : keyframes_) {
    if (keyframe.planes.empty()) continue;
    PlaneSightings sighting;
    sighting.id = keyframe.id;
    sighting.part = static_cast<int>(parts.Find(index_of.at(keyframe.id)));
    sighting.world_from_cam = graph_.Pose(keyframe.id);
    sighting.planes = keyframe.planes;
    sightings[Root(keyframe.segment)].push_back(std::move(sighting));
  }
  return sightings;
}

void Mapper::TrainVocabulary(MapperStageTimes* times) {
  const Clock::time_point start = Clock::now();
  std::vector<cv::Mat> descriptors;
  descriptors.reserve(keyframes_.size());
  for (const Keyframe& keyframe : keyframes_) {
    if (keyframe.features.descriptors.rows > 0)
      descriptors.push_back(keyframe.features.descriptors);
  }
  vocabulary_ =
      std::make_shared<const Vocabulary>(Vocabulary::Train(descriptors, options_.vocabulary));
  // Keyframes before the vocabulary are indexed now; they looked up nothing themselves, but later
  // keyframes find them.
  for (Keyframe& keyframe : keyframes_) IndexKeyframe(keyframe);
  times->place_recognition_s += SecondsSince(start);
}

void Mapper::IndexKeyframe(Keyframe& keyframe) {
  if (keyframe.indexed) return;
  keyframe.bow = vocabulary_->Transform(keyframe.features.descriptors);
  index_.Add(keyframe.id, keyframe.bow);
  keyframe.indexed = true;
}

std::function<Eigen::Matrix<double, 6, 6>(size_t edge)> Mapper::LoopCheckEdgeCovariance() const {
  const Eigen::Matrix<double, 6, 6> floor =
      DiagonalCovariance(options_.loop_check_link_sigma_m, options_.loop_check_link_sigma_rad);
  return [this, floor](size_t edge) {
    return Eigen::Matrix<double, 6, 6>(CovarianceOf(graph_.Edges()[edge].information) + floor);
  };
}

std::optional<std::vector<size_t>> Mapper::LoopCheckPath(const MapperLink& loop) const {
  return graph_.FirmestPath(loop.from, loop.to, LoopCheckEdgeCovariance(),
                            options_.loop_check_lever_m);
}

double Mapper::LoopChi2(const MapperLink& loop) const {
  const std::optional<std::vector<size_t>> path = LoopCheckPath(loop);
  return path ? LoopChi2On(loop, *path) : 0.0;  // no path: the graph has no opinion
}

double Mapper::LoopChi2On(const MapperLink& loop, const std::vector<size_t>& path) const {
  // The loop's pose against the graph's, M E^-1 in `from`'s frame. Not quite the pose graph's
  // edge error r (E = Exp(r) M, whose translation is this one's negated and turned by R(w)): the
  // two differ where the loop turns the graph far, and with r the 1 Hz walks let look-alike loops
  // through (seed 5 0.24 -> 2.66 m, seed 23 0.72 -> 8.76 m; loop_max_graph_chi2 was set on this
  // form).
  const Eigen::Isometry3d graph_to_in_from =
      graph_.Pose(loop.from).inverse() * graph_.Pose(loop.to);
  const Eigen::Matrix<double, 6, 1> error = LogSe3(loop.to_in_from * graph_to_in_from.inverse());
  const Eigen::Matrix<double, 6, 6> covariance =
      graph_.PathCovariance(loop.from, path, LoopCheckEdgeCovariance()) +
      CovarianceOf(loop.information) +
      DiagonalCovariance(options_.loop_check_slack_m, options_.loop_check_slack_rad);
  return error.dot(covariance.ldlt().solve(error));
}

double Mapper::LoopChi2AlongAxes(const MapperLink& loop) const {
  const std::optional<std::vector<size_t>> path = LoopCheckPath(loop);
  return path ? LoopChi2AlongAxesOn(loop, *path) : 0.0;
}

double Mapper::LoopChi2AlongAxesOn(const MapperLink& loop, const std::vector<size_t>& path) const {
  const AxesChain chain =
      ChainAlongAxes(graph_, loop.from, path, LoopCheckEdgeCovariance(), options_.loop_axes);
  const double end_sigma_rad = std::sqrt(chain.covariance.bottomRightCorner<3, 3>().trace());
  if (end_sigma_rad > DegToRad(options_.loop_axes_max_sigma_deg)) return 0.0;
  Eigen::Matrix<double, 6, 1> error;
  error.head<3>() = loop.to_in_from.translation() - chain.to_in_from.translation();
  const Eigen::AngleAxisd turn(loop.to_in_from.linear() * chain.to_in_from.linear().transpose());
  error.tail<3>() = turn.angle() * turn.axis();
  // The loop's own error r (true = Exp(r) M) moves its translation by its rotation error levered
  // over M's translation too.
  Eigen::Matrix<double, 6, 6> lever = Eigen::Matrix<double, 6, 6>::Identity();
  lever.topRightCorner<3, 3>() = -Skew(loop.to_in_from.translation());
  const Eigen::Matrix<double, 6, 6> covariance =
      chain.covariance + lever * CovarianceOf(loop.information) * lever.transpose() +
      DiagonalCovariance(options_.loop_check_slack_m, options_.loop_check_slack_rad);
  return error.dot(covariance.ldlt().solve(error));
}

bool Mapper::LoopFitsTheGraph(const MapperLink& loop) const {
  const bool graph_check = options_.loop_max_graph_chi2 > 0.0;
  const bool axes_check = options_.loop_max_axes_chi2 > 0.0;
  if (!graph_check && !axes_check) return true;
  // One path search serves both checks.
  const std::optional<std::vector<size_t>> path = LoopCheckPath(loop);
  if (!path) return true;  // nothing ties them: neither check has an opinion
  if (graph_check && LoopChi2On(loop, *path) > options_.loop_max_graph_chi2) return false;
  return !axes_check || LoopChi2AlongAxesOn(loop, *path) <= options_.loop_max_axes_chi2;
}

bool Mapper::SearchPlaces(Keyframe& keyframe, KeyframeReport* report) {
  Clock::time_point start = Clock::now();
  keyframe.bow = vocabulary_->Transform(keyframe.features.descriptors);
  const int root = Root(keyframe.segment);
  const bool other_segments = NumSegments() > 1;
  const bool loop_allowed = keyframe.id - last_loop_keyframe_ >= options_.loop_min_spacing;
  std::vector<PlaceCandidate> candidates;
  double reference_score = 1.0;
  if ((loop_allowed || other_segments) && options_.loop_candidates > 0) {
    // DBoW2's normalisation: how similar the keyframe is to its odometry neighbour says what a
    // high score is in this part of the building.
    if (keyframe.id > 0) {
      const Keyframe& previous = keyframes_[static_cast<size_t>(keyframe.id - 1)];
      if (previous.indexed) reference_score = Vocabulary::Score(keyframe.bow, previous.bow);
    }
    const int64_t newest_allowed = keyframe.id - options_.loop_exclude_recent;
    candidates = index_.Query(keyframe.bow, options_.loop_candidates, [&](int64_t id) {
      const int candidate_root = Root(keyframes_[static_cast<size_t>(id)].segment);
      if (candidate_root != root) return true;
      return loop_allowed && id <= newest_allowed;
    });
  }
  index_.Add(keyframe.id, keyframe.bow);
  keyframe.indexed = true;
  report->times.place_recognition_s += SecondsSince(start);

  for (const PlaceCandidate& candidate : candidates) {
    if (candidate.score < options_.loop_min_relative_score * reference_score) break;
    const Keyframe& target = keyframes_[static_cast<size_t>(candidate.id)];
    const RegistrationResult result =
        Register(keyframe, target, &report->times, nullptr, /*require_dense=*/true);
    if (!result.success || result.inliers < options_.loop_min_inliers) continue;
    MapperLink link = RegisteredLink(target.id, keyframe.id, result, LinkType::kLoopClosure);
    const int target_root = Root(target.segment);
    if (target_root == root && !LoopFitsTheGraph(link)) continue;
    if (target_root != root) {
      link.type = LinkType::kRelocalisation;
      // The older segment keeps its frame; the newer one moves into it.
      const int older = std::min(target_root, root);
      const int newer = std::max(target_root, root);
      // Rooms with the same furniture look the same from the same spot, and across segments the
      // pose graph has nothing to check a link against: a join waits until a second keyframe of
      // the segment, registered elsewhere in the map, agrees on where the segment lies.
      const Eigen::Isometry3d correction = JoinCorrection(newer, link);
      if (!JoinKeepsTheWalkPossible(older, newer, correction)) continue;
      const bool confirmed = pending_join_ && pending_join_->older == older &&
                             pending_join_->newer == newer &&
                             MotionWithin(pending_join_->correction.inverse() * correction,
                                          options_.join_max_disagreement_m,
                                          RadToDeg(options_.join_max_disagreement_rad));
      if (!confirmed) {
        pending_join_ = PendingJoin{older, newer, correction, link};
        break;
      }
      JoinSegments(older, newer, link);
      AddLink(pending_join_->link, report);
      pending_join_.reset();
    }
    AddLink(link, report);
    last_loop_keyframe_ = keyframe.id;
    if (link.type == LinkType::kLoopClosure && options_.local_loop_hops > 0) {
      OptimiseNear(links_.size() - 1, report);
    } else {
      Optimise(keyframe.id, report);
    }
    const MapperLink& added = links_.back();
    report->loop_closed = added.active;
    return link.type == LinkType::kRelocalisation;
  }
  return false;
}

std::vector<int64_t> Mapper::NearbyKeyframes(const Keyframe& keyframe) const {
  const int root = Root(keyframe.segment);
  const Eigen::Isometry3d world_from_cam = graph_.Pose(keyframe.id);
  const double min_cos = std::cos(DegToRad(options_.proximity_max_angle_deg));
  std::vector<std::pair<double, int64_t>> nearby;
  const int64_t newest_allowed = keyframe.id - options_.loop_exclude_recent;
  for (int64_t id = 0; id <= newest_allowed; ++id) {
    const Keyframe& other = keyframes_[static_cast<size_t>(id)];
    if (Root(other.segment) != root) continue;
    const Eigen::Isometry3d other_pose = graph_.Pose(id);
    const double distance = (other_pose.translation() - world_from_cam.translation()).norm();
    if (distance > options_.proximity_radius_m) continue;
    // Optical axes (each camera's z in the world).
    if (other_pose.linear().col(2).dot(world_from_cam.linear().col(2)) < min_cos) continue;
    nearby.emplace_back(distance, id);
  }
  const size_t kept = std::min(nearby.size(), static_cast<size_t>(options_.proximity_candidates));
  std::partial_sort(nearby.begin(), nearby.begin() + static_cast<std::ptrdiff_t>(kept),
                    nearby.end());
  std::vector<int64_t> ids;
  for (size_t i = 0; i < kept; ++i) ids.push_back(nearby[i].second);
  return ids;
}

bool Mapper::SearchNearby(const Keyframe& keyframe, KeyframeReport* report) {
  if (options_.proximity_candidates == 0 ||
      keyframe.id - last_loop_keyframe_ < options_.loop_min_spacing) {
    return false;
  }
  for (const int64_t id : NearbyKeyframes(keyframe)) {
    const Keyframe& target = keyframes_[static_cast<size_t>(id)];
    const Eigen::Isometry3d prior = graph_.Pose(id).inverse() * graph_.Pose(keyframe.id);
    const RegistrationResult result =
        Register(keyframe, target, &report->times, &prior, /*require_dense=*/true);
    if (!result.success || result.inliers < options_.proximity_min_inliers ||
        !MotionWithin(prior.inverse() * result.target_from_source,
                      options_.proximity_max_disagreement_m,
                      options_.proximity_max_disagreement_deg)) {
      continue;
    }
    AddLink(RegisteredLink(target.id, keyframe.id, result, LinkType::kLoopClosure), report);
    last_loop_keyframe_ = keyframe.id;
    if (options_.local_loop_hops > 0) {
      OptimiseNear(links_.size() - 1, report);
    } else {
      Optimise(keyframe.id, report);
    }
    report->loop_closed = links_.back().active;
    return report->loop_closed;
  }
  return false;
}

Eigen::Isometry3d Mapper::JoinCorrection(int newer_root, const MapperLink& link) const {
  // The pose `link.to` should have in the frame of `link.from`'s segment, and the rigid motion
  // that takes the whole of its segment there.
  if (Root(Get(link.to).segment) == newer_root) {
    return graph_.Pose(link.from) * link.to_in_from * graph_.Pose(link.to).inverse();
  }
  return graph_.Pose(link.to) * link.to_in_from.inverse() * graph_.Pose(link.from).inverse();
}

bool Mapper::JoinKeepsTheWalkPossible(int older_root, int newer_root,
                                      const Eigen::Isometry3d& correction) const {
  // Each place in time where the walk passes from one of the two segments to the other (other
  // segments' keyframes in between are skipped: they are not placed yet).
  const Keyframe* previous = nullptr;
  int previous_root = -1;
  for (const Keyframe& keyframe : keyframes_) {
    const int root = Root(keyframe.segment);
    if (root != older_root && root != newer_root) continue;
    if (previous != nullptr && previous_root != root && keyframe.walk >= 0 &&
        keyframe.walk == previous->walk) {
      const double gap_s =
          1e-9 * static_cast<double>(keyframe.timestamp_ns - previous->timestamp_ns);
      if (gap_s >= 0.0 && gap_s <= options_.walk_max_gap_s) {
        const auto placed = [&](const Keyframe& k, int k_root) {
          return k_root == newer_root ? correction * graph_.Pose(k.id) : graph_.Pose(k.id);
        };
        const Eigen::Isometry3d motion =
            placed(*previous, previous_root).inverse() * placed(keyframe, root);
        if (!MotionWithin(motion, options_.walk_max_speed_mps * gap_s + options_.walk_slack_m,
                          options_.walk_max_turn_rate_dps * gap_s + options_.walk_slack_deg)) {
          return false;
        }
      }
    }
    previous = &keyframe;
    previous_root = root;
  }
  return true;
}

void Mapper::JoinSegments(int older_root, int newer_root, const MapperLink& link) {
  const Eigen::Isometry3d correction = JoinCorrection(newer_root, link);
  for (const Keyframe& keyframe : keyframes_) {
    if (Root(keyframe.segment) == newer_root) {
      graph_.SetPose(keyframe.id, correction * graph_.Pose(keyframe.id));
    }
  }
  segment_parent_[static_cast<size_t>(newer_root)] = older_root;
}

void Mapper::Optimise(int64_t around, KeyframeReport* report, bool seeded) {
  const Clock::time_point start = Clock::now();
  TakeOptimisation(seeded ? graph_.OptimizeAroundSeeded(around, options_.pose_graph)
                          : graph_.OptimizeAround(around, options_.pose_graph),
                   report);
  report->optimised_locally = false;  // whatever moved before, the writer needs every pose
  report->moved.clear();
  report->times.optimisation_s += SecondsSince(start);
}

void Mapper::OptimiseNear(size_t link, KeyframeReport* report) {
  const Clock::time_point start = Clock::now();
  const PoseGraphSummary summary =
      graph_.OptimizeNear(link, options_.local_loop_hops, options_.local_loop_max_border_chi2_rise,
                          options_.pose_graph);
  // Only a step's first optimisation can leave the others where they were.
  const bool first = !report->optimised;
  TakeOptimisation(summary, report);
  report->optimised_locally = first && summary.local;
  if (report->optimised_locally) report->moved = summary.moved_poses;
  report->times.optimisation_s += SecondsSince(start);
}

void Mapper::TakeOptimisation(const PoseGraphSummary& summary, KeyframeReport* report) {
  for (size_t edge : summary.rejected_edges) {
    if (links_[edge].active) {
      links_[edge].active = false;
      ++report->links_rejected;
      report->rejected_links.push_back(edge);
    }
  }
  report->optimised = true;
}

SIGHTMAP_OPTIONS_JSON_LONG(
    MapperOptions,
    (features, registration, odometry_window, extra_odometry_links, extra_link_max_disagreement_m,
     extra_link_max_disagreement_deg, blind_link_max_deviation_mps, blind_link_max_deviation_dps,
     blind_link_slack_m, blind_link_slack_deg, bridged_sigma_factor, bridge_min_blind_step_s,
     bridge_frame, bridge_rotations_from_axes, manhattan_sigma_deg, manhattan_max_deviation_deg,
     manhattan, depth_downscale, vocabulary, vocabulary_training_keyframes, loop_exclude_recent,
     loop_candidates, loop_min_relative_score, loop_min_inliers, loop_min_spacing,
     proximity_candidates, proximity_radius_m, proximity_max_angle_deg, proximity_min_inliers,
     proximity_max_disagreement_m, proximity_max_disagreement_deg, local_loop_hops,
     local_loop_max_border_chi2_rise, pose_graph, seeded_final_solve, final_retry_max_loops,
     wall_tie_rounds, wall_ties),
    (join_max_disagreement_m, join_max_disagreement_rad, walk_max_speed_mps, walk_max_turn_rate_dps,
     walk_slack_m, walk_slack_deg, walk_max_gap_s, walk_max_tilt_deg, loop_max_graph_chi2,
     loop_check_link_sigma_m, loop_check_link_sigma_rad, loop_check_lever_m, loop_check_slack_m,
     loop_check_slack_rad, loop_max_axes_chi2, loop_axes_max_sigma_deg, loop_axes, link_min_sigma_m,
     link_min_sigma_rad, dense_refinement, dense, dense_max_correction_m, dense_max_correction_deg,
     dense_fit_max_correction_m, dense_fit_max_correction_deg, dense_fit_max_rms_ratio,
     dense_fit_max_intensity_ratio, dense_link_min_sigma_m, dense_link_min_sigma_rad))

}  // namespace sightmap::slam
