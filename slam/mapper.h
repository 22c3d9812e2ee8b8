// Incremental RGB-D mapping (the paper's Section 4.1.1, Figure 3): every keyframe arriving at about
// 1 Hz is registered against the newest keyframes of its segment (odometry), looked up in the bag
// of words for places seen before (loop closure, or relocalisation after tracking was lost),
// verified geometrically, and the pose graph is optimised when a loop is accepted.
//
// The mapper knows nothing of files or SQLite: the caller feeds keyframes and reads back poses,
// links and the vocabulary to store them. One thread calls it; it holds no threads of its own.
//
// Segments: when a keyframe cannot be registered to the last keyframes, the map does not stop.
// The keyframe starts a new segment whose poses live in their own frame (seeded with the last
// pose, since a person rarely teleports), every keyframe is kept, and each new keyframe of the
// segment is also looked up against the other segments; the first verified link joins the
// segments: the newer one is moved into the older one's frame and the graph optimised.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/link_type.h"
#include "core/rgbd_frame.h"
#include "core/tracking_state.h"
#include "slam/axes_path.h"
#include "slam/dense_alignment.h"
#include "slam/features.h"
#include "slam/manhattan_frame.h"
#include "slam/place_index.h"
#include "slam/pose_graph.h"
#include "slam/registration.h"
#include "slam/tracker.h"
#include "slam/vocabulary.h"
#include "slam/wall_ties.h"

namespace sightmap::slam {

struct MapperOptions {
  FeatureOptions features;
  RegistrationOptions registration;

  // Odometry registers a new keyframe to the newest keyframe of its segment first, then to older
  // ones up to this many back (at 1 Hz a walker may turn away for a second and back).
  int odometry_window = 4;
  // Besides the first successful odometry link, register to this many more keyframes of the window
  // for extra edges: a graph with a few short links per keyframe drifts less than a chain.
  int extra_odometry_links = 1;
  // A tracked keyframe's extra link (registered to an older keyframe) must place it within this
  // of where the tracked motion does, or it is dropped: tracked motions err by centimetres, and
  // odometry links are never switched off [m], [deg].
  double extra_link_max_disagreement_m = 0.15;
  double extra_link_max_disagreement_deg = 5.0;
  // A keyframe the tracker placed on its motion model (nothing registered for blind_s seconds)
  // may still register to older keyframes, but such a link must land within these rates times
  // the blind time (plus the slack) of the motion model's pose: a walker covers no more, and the
  // links further off matched a repeated desk or door (1 Hz seed 11: two such links put their
  // keyframes 2.2 and 3.2 m off while claiming 5 mm, and bent the whole walk) [m/s], [deg/s],
  // [m], [deg].
  double blind_link_max_deviation_mps = 1.0;
  double blind_link_max_deviation_dps = 60.0;
  double blind_link_slack_m = 0.05;
  double blind_link_slack_deg = 3.0;
  // A run of keyframes the tracker placed on its motion model is bridged once the motion after
  // it is measured (blind_bridge.h): each of their prior links then measures the velocity
  // interpolated between the registered motions on both sides of the run, with its standard
  // deviations this factor of the motion model's (the bridge errs about half as much as the
  // extrapolation). The 1 Hz hand-held walks (`slam_benchmark --track --fps 1 --frames 600`,
  // seeds 1/3/5/7/11/23): ATE 0.618 / 0.548 / 0.241 / 0.760 / 0.453 / 0.696 m without, 0.516 /
  // 0.272 / 0.177 / 0.715 / 0.313 / 0.380 m with it (0.326 and 0.405 m on seeds 11 and 23 with the
  // motion model's deviations kept). 0 turns it off [-].
  double bridged_sigma_factor = 0.5;
  // Only runs whose every blind step lasts this long are bridged. Between frames at the sensor's
  // rate the tracker's motion model extrapolates a velocity smoothed over many frames for a
  // fraction of a second, better than one from the keyframes' motions, which may span 0.1 s:
  // bridging every run moved keyframes 115-120 of the 10 Hz hand-held seed 11 walk 10 cm (a
  // 0.3 s step bridged from 0.1 s motions) and its ATE 0.0116 -> 0.0138 m. From a 1 Hz folder
  // the tracker extrapolates a whole second past its last frame [s].
  double bridge_min_blind_step_s = 0.5;
  // The frame a walker's velocity is kept in across a blind run (BridgeFrame): "world" or
  // "camera". By ground truth over the 1 Hz walks' blind steps (the true motions on both sides,
  // the true rotation), the world's velocity errs 26-28 mm at the median (p90 0.10-0.11 m), the
  // camera's 92-100 mm (p90 0.19 m): a hand-held camera looks about as the walker goes on. In
  // the maps the bridged links err 54 mm instead of 135 on the robot's 1 Hz walk too.
  std::string bridge_frame = "world";
  // A blind step whose both ends show the building's axes (manhattan_sigma_deg > 0) turns as
  // they say, the naming nearest the interpolated turn within twice
  // manhattan_max_deviation_deg: the bridged links' rotation errs 7.8 instead of 12.3 degrees at
  // the median (1 Hz hand-held seed 23), and the world's velocity is carried through it.
  bool bridge_rotations_from_axes = true;
  // The building's axes as a heading reference (slam/manhattan_frame.h): a keyframe whose depth
  // shows two of them gets an absolute rotation prior with this deviation per axis [deg] (0: off),
  // used in solves of whole parts while its estimate lies within manhattan_max_deviation_deg of
  // the measurement (PoseGraph::SetRotationPrior). The fits err 0.27 degrees at the median and
  // 0.64 at p90 on the simulated walks, where a bridged blind run errs 7-9 degrees at the median.
  // A wider bound lets a keyframe the motion model put 60-70 degrees off take another naming of
  // the axes, and the loops that would correct it are then switched off (1 Hz seed 7: ATE 0.57 m
  // at 10 degrees, 0.25 m at 15, 1.1 m at 20); 0.5 degrees of deviation gave seed 7 0.76 m at 10,
  // 2 degrees 0.58 m.
  double manhattan_sigma_deg = 1.0;
  double manhattan_max_deviation_deg = 15.0;
  ManhattanOptions manhattan;
  // The end's solve also ties parts that see the same wall along its normal (slam/wall_ties.h),
  // in this many rounds of tying and solving (0: off).
  int wall_tie_rounds = 2;
  WallTieOptions wall_ties;
  // Depth kept per keyframe for the dense verification, as 1/N of the image size (nearest
  // sample, so depth edges stay sharp): 160x120 at N = 4 is 38 KB a keyframe.
  int depth_downscale = 4;

  // Place recognition. The vocabulary is trained from the session's own first keyframes unless
  // one is given (SetVocabulary: a resumed model brings its own).
  VocabularyOptions vocabulary;
  int vocabulary_training_keyframes = 30;
  // Keyframes this recent (of the same segment) are never loop candidates: they are odometry's.
  int loop_exclude_recent = 20;
  // Candidates registered per keyframe, best bag-of-words score first.
  int loop_candidates = 3;
  // A candidate's score must reach this fraction of the score between the keyframe and its
  // odometry neighbour (DBoW2's normalised score: scores vary a lot between scenes).
  double loop_min_relative_score = 0.3;
  // A place registered with fewer inliers is not taken as a loop or relocalisation. Odometry
  // accepts 12 (keyframes a second apart on a bare wall have no more), but a revisit has other
  // keyframes to close on, and loops on few inliers over repeated texture are the ones that slide
  // by 10-30 cm (the office's doors and desks share their textures).
  int loop_min_inliers = 40;
  // Loops closer than this to the last accepted loop (in keyframes) are not searched: one
  // revisit gives one loop every few keyframes, not one every keyframe [keyframes].
  int loop_min_spacing = 3;
  // Proximity (RTAB-Map's detection by space): a revisit the bag of words missed (few or common
  // features: a wall with a door, a repeated desk) is still near where the graph puts it. When
  // place recognition closed no loop, up to proximity_candidates keyframes of the same part (not
  // the loop_exclude_recent newest) whose graph pose lies within proximity_radius_m and whose
  // viewing direction is within proximity_max_angle_deg are registered with the graph's relative
  // pose as prior, nearest first. Such a link must land within proximity_max_disagreement_* of
  // the prior (drift since the first visit is centimetres; a pose further off matched a look-alike)
  // and is then a loop closure like any other, refined and confirmed densely. 0 candidates: off.
  int proximity_candidates = 1;
  double proximity_radius_m = 1.0;        // [m]
  double proximity_max_angle_deg = 30.0;  // [deg]
  int proximity_min_inliers = 20;
  double proximity_max_disagreement_m = 1.0;     // [m]
  double proximity_max_disagreement_deg = 15.0;  // [deg]
  // A loop moves only the keyframes within local_loop_hops links of its ends when that fits the
  // rest of the map: it closes a cycle inside that window, and the links at the window's border
  // rise by at most local_loop_max_border_chi2_rise in chi-square; else the window grows
  // (PoseGraph::OptimizeNear). Most loops of a revisit fit a small window once its first loop
  // tied the walk to the map, and their cost does not grow with the map. 0 hops: every loop over
  // the whole part.
  int local_loop_hops = 10;
  double local_loop_max_border_chi2_rise = 1.0;
  // With a Cauchy loss on odometry too: odometry is never switched off, but a few links in a
  // hundred come from views without features (a bare wall) and err by centimetres and degrees
  // while their neighbours, refined densely, claim millimetres. The loss lets the links around it
  // and the loops outvote it instead of bending the map.
  PoseGraphOptions pose_graph = [] {
    PoseGraphOptions options;
    options.odometry_loss_scale = options.loop_loss_scale;
    return options;
  }();
  // OptimiseWhole also solves each part from seeds its links and the building's axes give
  // (PoseGraph::OptimizeAroundSeeded) and keeps the best fit: the solves while mapping can leave
  // a stretch joined by blind links turned where its axes priors no longer reach it (README, "The
  // final solve also from a seed"). The 10 Hz walks are unchanged.
  bool seeded_final_solve = true;
  // The end's solve first turns back on the loops the pose graph switched off while mapping, and
  // the whole graph judges them again (switching off the worst inconsistent loop, one solve at a
  // time). While mapping a loop is judged against the loops before it: a false loop accepted
  // first (10 Hz robot walk seed 5: 135 -> 513, slid 0.30 m up a bookcase's shelves) switched
  // off the four right loops that contradicted it later, and bent the map to 0.081 m; judged
  // together they outvote it (0.016 m). Each loop switched off again costs a solve of the whole
  // graph, so with more than this many switched off none is retried (a capture that lost that
  // many is not one a second judgement mends). 0: off [loops].
  int final_retry_max_loops = 100;
  // Two relocalisations of one segment must agree this well before the segments are joined
  // [m], [rad].
  double join_max_disagreement_m = 0.10;
  double join_max_disagreement_rad = 0.05;
  // Where odometry broke, the walk did not: between the last keyframe of one segment and the next
  // keyframe of the same capture, the sensor moved at most this fast. A join that would put them
  // further apart matched a look-alike place (offices repeat their rooms and furniture) and is
  // refused, however well its features agree. Gaps longer than walk_max_gap_s are not checked.
  double walk_max_speed_mps = 1.5;       // [m/s]
  double walk_max_turn_rate_dps = 60.0;  // [deg/s]
  double walk_slack_m = 0.5;             // added to the bound whatever the gap [m]
  double walk_slack_deg = 20.0;          // [deg]
  double walk_max_gap_s = 10.0;          // [s]
  // A walker holds the camera upright: between any two of its keyframes the camera's down axis
  // (image y) turns at most this far, whatever the gap (the hand-held walk at most 31 degrees,
  // the survey walk, which looks up at ceiling lights, 59; the real lounge frames 14). A
  // registration that turns it further matched a pattern symmetric under a half turn (a row of
  // locker doors, vents and labels read upside down: a 1 Hz loop 180 degrees off) and is refused
  // for every link, loop or relocalisation [deg].
  double walk_max_tilt_deg = 90.0;
  // A loop within one part must agree with where the pose graph puts its keyframe, within the
  // graph's own uncertainty between the two keyframes: the chi-square of the disagreement (6 dof)
  // against the covariance chained along the firmest path of links between them (PoseGraph::
  // PathCovariance; each link's covariance plus loop_check_link_sigma_*, since registered links
  // claim millimetres and their errors are not independent) plus the loop's own and the slack,
  // at most loop_max_graph_chi2. Without it, loops onto an identical room 10-23 m away passed
  // graphs held loosely by motion-model links (1 Hz walks, seeds 1 and 5, chi-square 60 and 94
  // here), while right loops that turn a keyframe back by 150 degrees after a blind stretch score
  // up to 120: the limit trades some of those for the look-alikes. 0: no check [m], [rad], [m].
  double loop_max_graph_chi2 = 50.0;
  double loop_check_link_sigma_m = 0.02;
  double loop_check_link_sigma_rad = 0.01;
  double loop_check_lever_m = 3.0;  // weighs rotation against translation in the path's choice
  double loop_check_slack_m = 0.25;
  double loop_check_slack_rad = 0.0;
  // The same loop against where the measurements alone put its keyframe, chained along that path
  // with every rotation a keyframe's axes prior fixes held to the building's axes
  // (ChainAlongAxes, loop_axes), at most loop_max_axes_chi2 (same covariances and slack). While
  // mapping the graph's estimate between keyframes minutes apart can be off by 60-110 degrees
  // (1 Hz robot walk), so the check above must be wide and let a loop onto an identical room 10 m
  // away through (chi-square 9-22); held to the axes, a blind link's rotation error stops at the
  // next keyframe that sees them and that loop scores 87-129 (seeds 5, 11). Judged only when the
  // chain's rotation sigma at the loop's end is within loop_axes_max_sigma_deg: farther, the
  // linearised test means nothing (right loops 79 degrees off with a 69-degree sigma scored
  // 60-270).
  double loop_max_axes_chi2 = 60.0;       // 0: no check
  double loop_axes_max_sigma_deg = 40.0;  // [deg]
  AxesChainOptions loop_axes;
  // Registration's information matrix assumes independent depth errors and so claims sub-millimetre
  // precision from a few hundred inliers; systematic errors (depth bias, calibration) do not shrink
  // with the inlier count. This floor is added to every link's covariance so the pose graph weighs
  // links realistically and its chi-square test of loops means something [m], [rad].
  double link_min_sigma_m = 0.01;
  double link_min_sigma_rad = 0.003;

  // Dense refinement (see dense_alignment.h): every link registration finds (odometry, the
  // tracker's motions, loops and relocalisations) is refined by dense RGB-D alignment from the
  // features' pose, which costs about 15 ms and a 320x240 grey and depth image a keyframe.
  // A refinement that moves the pose further than these bounds slid along a bare wall: an odometry
  // link keeps the features' pose, a place (loop or relocalisation) is refused, since a revisit has
  // other keyframes to close on and the loops refinement cannot confirm are the ones 10-30 cm off
  // [m], [deg].
  bool dense_refinement = true;
  DenseAlignmentOptions dense;
  double dense_max_correction_m = 0.05;
  double dense_max_correction_deg = 2.0;
  // An odometry link's refinement may move it up to dense_fit_max_correction_* when the frames
  // agree better there than at the features' pose (DenseAligner::Fit): at least the share of
  // paired pixels, depth residuals (RMS, in units of the depth noise) at most
  // dense_fit_max_rms_ratio x those at the start, and grey levels differing by at most
  // dense_fit_max_intensity_ratio x as much. Repeated texture (radiator fins, tiled plant boxes,
  // window grids) puts features 5-14 cm and 1-3 degrees off where dense alignment finds the right
  // pose (robot walk, seed 11: the depth residuals fall to 0.73-0.87 x those at the features'
  // pose); a slide along a bare wall fits no better and is still refused. Places keep the plain
  // bound [m], [deg].
  double dense_fit_max_correction_m = 0.15;
  double dense_fit_max_correction_deg = 4.0;
  double dense_fit_max_rms_ratio = 0.9;
  double dense_fit_max_intensity_ratio = 1.1;
  // The floor of a refined link's covariance, as link_min_sigma_* for the features' links: refined
  // links err by about 2 mm against the simulator's ground truth [m], [rad].
  double dense_link_min_sigma_m = 0.003;
  double dense_link_min_sigma_rad = 0.001;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const MapperOptions& options);
void from_json(const nlohmann::json& json, MapperOptions& options);

// kPrior: the tracker's motion model across seconds where nothing registered (a bare wall filled
// the view); its covariance grows with the blind time, so a later loop closure corrects it.
struct MapperLink {
  int64_t from = 0;
  int64_t to = 0;
  // Pose of `to` in `from`'s camera frame: world_from_from^-1 * world_from_to.
  Eigen::Isometry3d to_in_from = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
  LinkType type = LinkType::kOdometry;
  int inliers = 0;
  bool active = true;  // false once the pose graph rejected it as inconsistent
};

// Time of each stage for one keyframe [s].
struct MapperStageTimes {
  double features_s = 0.0;
  double matching_s = 0.0;
  double ransac_s = 0.0;  // RANSAC and refinement
  double verification_s = 0.0;
  double dense_s = 0.0;              // dense refinement of registered links
  double place_recognition_s = 0.0;  // bag of words, index query (and training once)
  double optimisation_s = 0.0;
  double total_s = 0.0;
  int registrations = 0;  // pairs registered (odometry and place candidates), what matching costs
};

struct KeyframeReport {
  int64_t id = 0;
  int segment = 0;
  TrackingState state = TrackingState::kTracking;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  std::vector<MapperLink> new_links;
  bool loop_closed = false;
  bool optimised = false;
  // Of the poses, only those near the new loop moved (MapperOptions::local_loop_hops): the
  // writer need not store the others again.
  bool optimised_locally = false;
  std::vector<int64_t> moved;          // the keyframes that moved, when optimised_locally
  int links_rejected = 0;              // loop links the pose graph switched off in this step
  std::vector<size_t> rejected_links;  // their indices in Links()
  // Loop links switched off before and back on after this step (OptimiseWhole's second
  // judgement, MapperOptions::final_retry_max_loops), indices in Links().
  std::vector<size_t> reactivated_links;
  // Older prior links whose measurement this step replaced (a bridged blind run), indices in
  // Links(); the keyframe's own links are in new_links.
  std::vector<size_t> revised_links;
  std::string odometry_failure;  // why odometry failed, when state != kTracking
  int features = 0;
  MapperStageTimes times;
};

class Mapper {
 public:
  Mapper(const Intrinsics& camera, const MapperOptions& options = MapperOptions());
  ~Mapper();
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  // Registers and inserts one keyframe (colour BGR 8-bit, depth 16-bit mm registered to colour,
  // both of the camera's size). Throws InvalidArgument for images that do not fit the camera.
  KeyframeReport AddKeyframe(TimestampNs timestamp_ns, const cv::Mat& color,
                             const cv::Mat& depth_mm);
  // Inserts a keyframe the Tracker emitted (features computed, depth_small at 1/depth_downscale;
  // its full-size images give the dense refinement's). Its motion from the previous keyframe (the
  // last one added) becomes the odometry link, of type kPrior when the motion model made it, so
  // the keyframe continues the segment of the one before whatever registration does;
  // registrations to older keyframes of the odometry window add links as in AddKeyframe. Without
  // a motion (the tracker's first keyframe) it is placed as AddKeyframe places a keyframe that
  // registers to nothing: a new segment for place recognition to join.
  KeyframeReport AddTrackedKeyframe(TrackedKeyframe keyframe);
  // Inserts a keyframe whose pose is known (a survey with ground truth): no registration and no
  // loop search, one odometry link to the previous keyframe carrying the known relative pose. It
  // still gets features and is indexed for place recognition, so the model it makes serves photo
  // localisation exactly like a mapped one. For evaluating the matching phase apart from SLAM.
  KeyframeReport AddKeyframeAtPose(TimestampNs timestamp_ns, const cv::Mat& color,
                                   const cv::Mat& depth_mm,
                                   const Eigen::Isometry3d& world_from_cam);
  // Where the map's first keyframe is (before the first AddKeyframe); the identity by default. A
  // source with ground truth anchors the map in its frame this way, so a scene's labels and
  // photos' true poses are in the model's frame.
  void SetFirstPose(const Eigen::Isometry3d& world_from_cam);

  // Adds a link found elsewhere (a user's, or a test's deliberately wrong one) between two
  // keyframes of one segment and optimises; returns what the optimisation did.
  KeyframeReport AddExternalLink(const MapperLink& link);

  // Optimises every part of the map over all its links, as the end of a capture: a loop that fit
  // a window of its ends moved only that window (local_loop_hops), and what the windows left
  // between them is settled here. Returns what the optimisations did (world_from_cam and id of
  // the newest keyframe; every pose may have moved).
  KeyframeReport OptimiseWhole();

  // Resuming a stored map (before the new session's first AddKeyframe): each stored keyframe with
  // its features, depth (full size or already 1/depth_downscale) and optimised pose, in id order
  // from 0, then the stored links. Restored keyframes are not registered again; each link joins
  // the segments of its ends without moving poses. With its full-size colour (optional) a
  // restored keyframe's links to the new session are densely refined too. Returns the keyframe's
  // mapper id.
  int64_t RestoreKeyframe(TimestampNs timestamp_ns, Features features, const cv::Mat& depth_mm,
                          const Eigen::Isometry3d& world_from_cam,
                          const cv::Mat& color = cv::Mat());
  void RestoreLink(const MapperLink& link);
  // The next keyframe starts a new segment (a new session, or a jump the caller knows of): it is
  // relocalised against the map through place recognition instead of registered to the last one.
  void StartNewSegment() {
    start_new_segment_ = true;
    ++walk_;  // the capture is interrupted: the next keyframe starts another walk
  }
  // Undoes StartNewSegment for the next keyframe: it continues the walk of the newest keyframe (a
  // replay resumed right after its last stored frame), so it is registered to the newest
  // keyframes as odometry, and starts a segment of its own only when that fails. Without it the
  // resumed walk hangs off the stored map by its first relocalisation alone.
  void ContinueWalk() { start_new_segment_ = false; }

  // A vocabulary to use instead of training one (before the first keyframe).
  void SetVocabulary(std::shared_ptr<const Vocabulary> vocabulary);
  // Null until trained (after vocabulary_training_keyframes) or set.
  std::shared_ptr<const Vocabulary> vocabulary() const { return vocabulary_; }

  const Intrinsics& camera() const { return camera_; }
  size_t NumKeyframes() const { return keyframes_.size(); }
  int NumLoopClosures() const;  // accepted and still active
  int NumSegments() const;      // segments not joined to another
  int NumPriorLinks() const;    // links made by the tracker's motion model
  // Keyframes whose depth showed the building's axes (a rotation prior each).
  int NumManhattanKeyframes() const { return static_cast<int>(graph_.NumRotationPriors()); }
  TrackingState tracking_state() const { return state_; }

  // Current estimates, after the latest optimisation, in keyframe order.
  std::vector<StampedPose> Trajectory() const;
  Eigen::Isometry3d WorldFromCam(int64_t id) const;
  int SegmentOf(int64_t id) const;
  const std::vector<MapperLink>& Links() const { return links_; }
  // The chi-square of a loop's disagreement with where the graph puts its `to` keyframe relative
  // to its `from` (both of one part), against the graph's uncertainty between them
  // (MapperOptions::loop_max_graph_chi2 says how it is made); 0 when no link joins them. Throws
  // when either keyframe is unknown.
  double LoopChi2(const MapperLink& loop) const;
  // The same disagreement against the loop's keyframes' relative pose chained along that path's
  // measurements with every rotation the building's axes fix held to them (ChainAlongAxes)
  // instead of the graph's estimate (MapperOptions::loop_max_axes_chi2); 0 when no link joins
  // them or the chain's rotation at `to` is not known within loop_axes_max_sigma_deg.
  double LoopChi2AlongAxes(const MapperLink& loop) const;
  const Features& FeaturesOf(int64_t id) const;

 private:
  // Adds a keyframe's pose to the pose graph; the map's first is fixed there.
  void AddGraphPose(int64_t id, const Eigen::Isometry3d& world_from_cam);
  struct Keyframe {
    int64_t id = 0;
    TimestampNs timestamp_ns = 0;
    int segment = 0;
    // The continuous capture the keyframe came from (a new one after StartNewSegment); -1 for a
    // restored keyframe, whose capture is over.
    int walk = -1;
    Features features;
    cv::Mat depth_small;  // depth_downscale x smaller, nearest samples
    // Empty when dense refinement is off or the colour is unknown; packed (and `dense` emptied)
    // once the keyframe leaves the odometry window.
    DenseImage dense;
    PackedDenseImage packed_dense;
    bool HasDense() const { return !dense.empty() || !packed_dense.empty(); }
    bool indexed = false;
    BowVector bow;
    // Index in links_ of the link carrying the tracker's motion from the previous keyframe, and
    // how the tracker found that motion; -1 without one (not tracked, the walk's first keyframe,
    // restored).
    int64_t motion_link = -1;
    MotionSource motion_source = MotionSource::kPrior;
    // The building's axes as its depth shows them (FitManhattanFrame), when it shows two.
    std::optional<Eigen::Matrix3d> cam_from_axes;
    std::vector<AxisPlane> planes;  // along those axes (FindAxisPlanes)
  };

  // The Manhattan options for a keyframe's depth (full size, or depth_downscale x smaller).
  ManhattanOptions ManhattanOptionsFor(const cv::Mat& depth_mm) const;
  // The building's axes in a keyframe's depth, when the Manhattan prior is on and the depth shows
  // two of them, and then its planes along them (when wall ties are on).
  void MeasureAxesAndWalls(const cv::Mat& depth_mm, Keyframe* keyframe) const;
  // Every keyframe's planes with its pose and rigid part, for TieWalls, by segment root.
  std::map<int, std::vector<PlaneSightings>> PlaneSightingsOfParts() const;
  // Gives a keyframe in the graph its rotation prior (the first one places the building's axes).
  void AddRotationPrior(const Keyframe& keyframe);
  // A keyframe's features and small depth (checks the images; times features_s in `report`).
  Keyframe MakeKeyframe(TimestampNs timestamp_ns, const cv::Mat& color, const cv::Mat& depth_mm,
                        KeyframeReport* report) const;
  // Registers `keyframe` to the newest keyframes (all of the odometry window, or those before the
  // last when `motion` already links it to the last) and inserts it with its links; then place
  // recognition. The shared body of AddKeyframe and AddTrackedKeyframe.
  void Insert(Keyframe keyframe, const KeyframeMotion* motion, KeyframeReport* report);
  // When `motion` (registered) ends a run of keyframes placed on the motion model, replaces their
  // prior links' measurements by the bridge between the registered motion before the run and
  // `motion` (MapperOptions::bridged_sigma_factor) and lists them in report->revised_links.
  void BridgeBlindRunBefore(const Keyframe& keyframe, const KeyframeMotion& motion,
                            KeyframeReport* report);
  // Insert's stages, in order. The tracked motion (none without one), refined densely when
  // features registered it (`refined`).
  std::optional<KeyframeMotion> RefinedMotion(const Keyframe& keyframe,
                                              const KeyframeMotion* tracked_motion,
                                              MapperStageTimes* times, bool* refined) const;
  // Where the new keyframe probably is, in the last keyframe's segment frame (a map with one).
  Eigen::Isometry3d PredictPose(const KeyframeMotion* motion) const;
  // The new keyframe's registered odometry links to the newest keyframes (odometry_window,
  // extra_odometry_links), each checked against `predicted` when a motion was tracked or guessed;
  // the first failure's reason goes into the report.
  std::vector<MapperLink> RegisterOdometry(const Keyframe& keyframe, const KeyframeMotion* motion,
                                           const Eigen::Isometry3d& predicted,
                                           KeyframeReport* report) const;
  // The link of a tracked (or guessed) motion from the last keyframe to keyframe `id`.
  MapperLink TrackedMotionLink(int64_t id, const KeyframeMotion& motion, bool refined) const;
  // The new keyframe's initial pose: where a measured motion (registered or dense) puts it, else
  // the first registered link's, else where the motion model guessed (`predicted`), else the last
  // keyframe's.
  Eigen::Isometry3d PlaceKeyframe(const std::vector<MapperLink>& registered,
                                  const KeyframeMotion* motion,
                                  const Eigen::Isometry3d& predicted) const;
  // The segment of the first odometry link's keyframe, or a new one when there is none (lost) or
  // one was asked for.
  void AssignSegment(const std::vector<MapperLink>& odometry, const KeyframeMotion* motion,
                     Keyframe* keyframe, KeyframeReport* report);
  // Without a vocabulary, trains one once enough keyframes are in; with one, searches places for a
  // loop or a relocalisation and, without either, nearby keyframes. True when relocalised.
  bool RecognisePlace(Keyframe& keyframe, KeyframeReport* report);
  // Whether a registration's pose for a keyframe placed on the motion model lies within the
  // blind_link_* bounds of the model's pose after blind_s seconds.
  bool WithinBlindMotion(const Eigen::Isometry3d& registered, const Eigen::Isometry3d& predicted,
                         double blind_s) const;
  // Whether a registration's pose for a new keyframe agrees with the one its tracked motion gives.
  bool AgreesWithTrackedMotion(const Eigen::Isometry3d& registered,
                               const Eigen::Isometry3d& tracked) const;
  Keyframe& Get(int64_t id);
  const Keyframe& Get(int64_t id) const;
  int Root(int segment) const;
  void AddLink(const MapperLink& link, KeyframeReport* report);
  // Registers by features and refines densely; the result's information is floored for the pose
  // graph (link_min_sigma_*, or dense_link_min_sigma_* when refined). With `require_dense` a
  // registration dense alignment cannot confirm fails (when both keyframes have dense images).
  RegistrationResult Register(const Keyframe& source, const Keyframe& target,
                              MapperStageTimes* times, const Eigen::Isometry3d* prior,
                              bool require_dense) const;
  // The keyframe's dense image prepared for alignment (kept for the newest keyframes).
  std::shared_ptr<DenseAligner::Frame> Prepared(const Keyframe& keyframe) const;
  // Packs the dense image of the keyframe that just left the odometry window.
  void PackOldDenseImages();
  // Refines `target_from_source` and replaces `information` (floored) by dense alignment from
  // it; false, leaving both as they were, when either keyframe has no dense image or the
  // alignment failed or moved the pose beyond dense_max_correction_*.
  // With `odometry`, a larger correction the frames fit better at is taken too
  // (MapperOptions::dense_fit_*).
  bool RefineDensely(const Keyframe& source, const Keyframe& target,
                     Eigen::Isometry3d* target_from_source,
                     Eigen::Matrix<double, 6, 6>* information, MapperStageTimes* times,
                     bool odometry) const;
  // Whether the frames agree better at the refined pose than at the start (dense_fit_*).
  bool FitsBetter(const DenseFit& refined, const DenseFit& start) const;
  void TrainVocabulary(MapperStageTimes* times);
  void IndexKeyframe(Keyframe& keyframe);
  // Whether a loop's disagreement with the graph is within MapperOptions::loop_max_graph_chi2.
  bool LoopFitsTheGraph(const MapperLink& loop) const;
  // OptimiseWhole's second judgement: turns the loops switched off while mapping back on
  // (MapperOptions::final_retry_max_loops) and returns their indices in links_.
  std::vector<size_t> RetryRejectedLoops();
  // Leaves in the report only what changed since before RetryRejectedLoops: retried loops
  // switched off again drop out of rejected_links, those kept on are reactivated_links.
  void NetRetriedLoops(const std::vector<size_t>& retried, KeyframeReport* report) const;
  // What both loop checks chain along: each link's covariance plus loop_check_link_sigma_*, and
  // the firmest path between the loop's keyframes by it (nullopt: nothing ties them).
  std::function<Eigen::Matrix<double, 6, 6>(size_t edge)> LoopCheckEdgeCovariance() const;
  std::optional<std::vector<size_t>> LoopCheckPath(const MapperLink& loop) const;
  // LoopChi2 and LoopChi2AlongAxes on that path.
  double LoopChi2On(const MapperLink& loop, const std::vector<size_t>& path) const;
  double LoopChi2AlongAxesOn(const MapperLink& loop, const std::vector<size_t>& path) const;
  // Looks up `keyframe` for loop closures (same segment) or relocalisation (other segments);
  // true when it joined two segments.
  bool SearchPlaces(Keyframe& keyframe, KeyframeReport* report);
  // Looks for a loop closure among the keyframes the graph places near `keyframe`
  // (MapperOptions::proximity_candidates); true when one was accepted.
  bool SearchNearby(const Keyframe& keyframe, KeyframeReport* report);
  // The keyframes SearchNearby registers to, nearest first.
  std::vector<int64_t> NearbyKeyframes(const Keyframe& keyframe) const;
  Eigen::Isometry3d JoinCorrection(int newer_root, const MapperLink& link) const;
  // False when moving the newer segment by `correction` would make the walk jump: see
  // MapperOptions::walk_max_speed_mps.
  bool JoinKeepsTheWalkPossible(int older_root, int newer_root,
                                const Eigen::Isometry3d& correction) const;
  void JoinSegments(int older_root, int newer_root, const MapperLink& link);
  // Optimises the part of the map joined to keyframe `around` (where a link was just added);
  // `seeded`: also from poses seeded by its links (PoseGraph::OptimizeAroundSeeded).
  void Optimise(int64_t around, KeyframeReport* report, bool seeded = false);
  // Optimises after link `link` (an index into links_) was added: the keyframes within
  // local_loop_hops links of it when that fits the rest, else more (PoseGraph::OptimizeNear).
  void OptimiseNear(size_t link, KeyframeReport* report);
  // Marks the links an optimisation switched off and the report optimised.
  void TakeOptimisation(const PoseGraphSummary& summary, KeyframeReport* report);

  Intrinsics camera_;
  MapperOptions options_;
  std::vector<Keyframe> keyframes_;  // id = index
  std::vector<MapperLink> links_;    // links_[i] is the pose graph's edge i
  PoseGraph graph_;
  std::unique_ptr<DenseAligner> aligner_;  // null when dense refinement is off
  // The newest keyframes prepared for alignment (each is aligned to its neighbours up to four
  // times), by id; older ones, aligned only as loop candidates, are prepared each time.
  mutable std::map<int64_t, std::shared_ptr<DenseAligner::Frame>> prepared_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  PlaceIndex index_;
  std::vector<int> segment_parent_;  // union-find over segments
  TrackingState state_ = TrackingState::kTracking;
  int64_t last_loop_keyframe_ = -1000000;
  bool vocabulary_given_ = false;
  bool start_new_segment_ = false;
  int walk_ = 0;  // Keyframe::walk of the next new keyframe
  Eigen::Isometry3d first_world_from_cam_ = Eigen::Isometry3d::Identity();
  // A relocalisation waiting for a second keyframe to agree before two segments are joined.
  struct PendingJoin {
    int older = 0;
    int newer = 0;
    Eigen::Isometry3d correction;  // what the join would apply to the newer segment
    MapperLink link;
  };
  std::optional<PendingJoin> pending_join_;
};

}  // namespace sightmap::slam
