// The stages of Locator::Locate, each a function of its inputs so it can be tested alone:
//   PreparePhoto -> RetrieveCandidates -> GroupPlaces -> (per place) MatchPlace -> VerifyPlace
//   -> (when none was accepted) JudgeViewsAgain -> Decide.
// The Locator loads the model's keyframes once and strings these together per photo; tests build
// keyframes, places and matches by hand.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/features.h"
#include "identify/locator.h"
#include "slam/place_index.h"
#include "slam/vocabulary.h"
#include "slam/vote_index.h"

namespace sightmap::identify {

// Why a stage ended the search for a pose, in the reason classes a client explains.
struct Refusal {
  UnmatchedReason code = UnmatchedReason::kNone;
  std::string reason;  // one sentence, with the figures
};

// One keyframe as the locator matches against it.
struct LocatorKeyframe {
  KeyframeId id;                   // for a synthetic view, the keyframe it was rendered from
  SyntheticViewId synthetic_view;  // valid for a synthetic view
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  Eigen::Vector3d view_direction = Eigen::Vector3d::UnitZ();  // camera z in the world
  // The features that have a 3D point: their descriptors (one 32-byte ORB row each, or one
  // 128-byte RootSIFT row) and world points [m].
  cv::Mat descriptors;
  std::vector<cv::Point3f> world_points;
  std::vector<int> nodes;  // per descriptor: its vocabulary node at match_node_level (> 0 only)
  std::vector<size_t> neighbours;  // slots, nearest first
  // For the view check (LocatorOptions::min_view_agreement); null for a synthetic view or a
  // keyframe without depth. Shared by the ORB and RootSIFT slots of the same keyframe.
  std::shared_ptr<const KeyframeThumbnail> thumbnail;
};

// For each keyframe, up to max_neighbours others within neighbour_radius_m looking within
// neighbour_max_angle_deg of it (and holding 3D points), nearest first.
void FindNeighbours(const LocatorOptions& options, std::vector<LocatorKeyframe>* keyframes);

// The photo's keypoints bucketed into square cells, for window searches around projected points.
class PhotoGrid {
 public:
  PhotoGrid() = default;
  PhotoGrid(const std::vector<cv::Point2f>& points, int width, int height, double cell_px);

  // Calls visit(index) for every keypoint in the cells a window of `radius` around p touches.
  template <typename Visit>
  void ForEachNear(const cv::Point2f& p, double radius, Visit visit) const {
    if (cells_.empty()) return;
    const int c0 = std::max(0, static_cast<int>((p.x - radius) / cell_));
    const int c1 = std::min(cols_ - 1, static_cast<int>((p.x + radius) / cell_));
    const int r0 = std::max(0, static_cast<int>((p.y - radius) / cell_));
    const int r1 = std::min(rows_ - 1, static_cast<int>((p.y + radius) / cell_));
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) {
        for (int i : cells_[static_cast<size_t>(r * cols_ + c)]) visit(i);
      }
    }
  }

 private:
  double cell_ = 1.0;
  int cols_ = 0;
  int rows_ = 0;
  std::vector<std::vector<int>> cells_;
};

// Stage 1: the photo as matched: grey, downscaled to max_image_side_px, its features, and the
// intrinsics to try.
struct PreparedPhoto {
  cv::Size size;  // of the feature image [px]
  // Intrinsics to try, at the photo's full resolution and at the feature image's: the given
  // ones, or one per focal_candidates_35mm when none are given.
  std::vector<Intrinsics> full_candidates;
  std::vector<Intrinsics> feature_candidates;
  bool intrinsics_given = false;
  Features features;  // what is matched: ORB or RootSIFT (LocatorOptions::matcher)
  // ORB descriptors, what retrieval ranks keyframes by (features' when the matcher is ORB).
  cv::Mat retrieval_descriptors;
  std::vector<cv::Point2f> points;  // keypoint positions, at the feature image's scale
  std::vector<int> nodes;           // per descriptor, for matching bounded by vocabulary nodes
  PhotoGrid grid;                   // cells of guided_radius_px
  // The photo as the view check compares it (AgreementImage); empty with the check off.
  cv::Mat agreement_image;
  // Cells of a 4x4 grid holding at least 20 features: a bare ceiling or wall fills one or two.
  int detail_cells = 0;
  std::optional<Refusal> refusal;  // kFewFeatures: too small, or too few features to match
};
// `photo` is 8-bit grey, BGR or BGRA and not empty; given intrinsics are checked (throws Error
// when unusable) and scaled to the photo when made for another size.
PreparedPhoto PreparePhoto(const cv::Mat& photo, const std::optional<Intrinsics>& intrinsics,
                           const LocatorOptions& options);
// What RootSiftPhoto takes from the ORB-prepared photo: its intrinsics candidates, detail cells
// and ORB retrieval descriptors (a header sharing their data), without its features. Small
// enough to hand another thread while the ORB search goes on with `orb`.
PreparedPhoto RootSiftSeed(const PreparedPhoto& orb);

// Stage 1 for the RootSIFT matcher: the same photo (`orb` is its PreparePhoto) matched with
// RootSIFT (sift_photo_features) at sift_image_side_px; intrinsics, detail cells and
// the ORB retrieval descriptors are orb's.
PreparedPhoto RootSiftPhoto(const cv::Mat& photo, const PreparedPhoto& orb,
                            const LocatorOptions& options);

// Stage 2: retrieval. The best `count` candidates for the photo's descriptors by the method
// named: the bag-of-words `index`'s, or its best vote_shortlist re-ranked by `votes`; best first.
// In a model of no more keyframes than retrieval_candidates, or without a vocabulary, every
// keyframe holding 3D points is a candidate too (a few keyframes are cheaper to verify than to
// rank, and a vocabulary trained on them ranks poorly).
std::vector<slam::PlaceCandidate> RetrieveCandidates(
    const cv::Mat& descriptors, LocatorOptions::Retrieval method, int count,
    const slam::Vocabulary& vocabulary, const slam::PlaceIndex& index, const slam::VoteIndex& votes,
    const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options);

// Stage 2, for measurement only: `candidates` with the real keyframes whose ids are in `first`
// before the others: those among `candidates` in their order, then the rest in `first`'s order
// (score 0). Ids of no keyframe in `keyframes`, and synthetic views, are left out. Empty `first`:
// `candidates` as they are.
std::vector<slam::PlaceCandidate> PutKeyframesFirst(
    const std::vector<slam::PlaceCandidate>& candidates, const std::vector<KeyframeId>& first,
    const std::vector<LocatorKeyframe>& keyframes);

// Stage 2b: the candidates of `first`, then those of `then` not among them, each in its order (a
// second retrieval's candidates tried before the first's).
std::vector<slam::PlaceCandidate> MergeCandidates(const std::vector<slam::PlaceCandidate>& first,
                                                  const std::vector<slam::PlaceCandidate>& then);

// Stage 3: candidates grouped into places. A candidate within place_radius_m of an earlier
// place's head and looking within place_max_angle_deg of it joins that place (same part of the
// building, similar view), so each place is matched once against its keyframes' and their
// neighbours' 3D features rather than keyframe by keyframe. At most `max_places` (the first
// look's max_places, the second look's second_look_max_places, the twins' twin_places), in the
// order of their best candidate.
struct Place {
  size_t head = 0;            // the best-scoring candidate's slot
  std::vector<size_t> slots;  // candidates and their neighbours, each once
};
// Candidates from `reserve_from` on (the reserve_candidates after retrieval_candidates) never
// join a place an earlier candidate made: they only make places of their own.
std::vector<Place> GroupPlaces(const std::vector<slam::PlaceCandidate>& candidates,
                               size_t reserve_from, int max_places,
                               const std::vector<LocatorKeyframe>& keyframes,
                               const LocatorOptions& options);

// Stage 4: 2D-3D matches of the photo against the union of a place's keyframes.
struct PlaceMatches {
  cv::Mat model_descriptors;              // every 3D feature of the place, one row each
  std::vector<cv::Point3f> model_points;  // their world points
  std::vector<size_t> model_slots;        // the keyframe each comes from
  std::vector<cv::Point3f> object;        // per correspondence: the model point
  std::vector<cv::Point2f> image;         // and the photo keypoint
  std::vector<int> object_model;          // and its row in model_points
};
// A photo descriptor's nearest model descriptor within max_descriptor_distance (ORB) or
// sift_max_distance (RootSIFT) passes when it beats match_ratio x the nearest descriptor of another
// 3D point (more than same_point_m away: the same point seen by a neighbour keyframe confirms
// rather than competes).
PlaceMatches MatchPlace(const PreparedPhoto& photo, const Place& place,
                        const std::vector<LocatorKeyframe>& keyframes,
                        const LocatorOptions& options);

// What PnP found for one place and one set of intrinsics.
struct PoseHypothesis {
  bool valid = false;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  Intrinsics intrinsics;  // at the feature image's scale
  std::vector<int> inliers;
};

// Stage 5: a place's pose, and whether it passes the checks.
struct PlaceVerdict {
  PoseHypothesis pose;  // invalid when PnP found nothing
  int matches = 0;      // correspondences the pose was last refined on
  int projected = 0;    // place points the guided pose projects into the photo
  int inliers = 0;
  cv::Mat inlier_descriptors;  // their model descriptors, one row each
  // Per inlier, its cell of an 8x8 grid over the photo (row-major), and the cells holding one:
  // what part of the photo this place explains.
  std::vector<uint8_t> inlier_fine_cells;
  uint64_t fine_cell_mask = 0;
  // The mean of the inliers' model points (world): which things the pose explains the photo with
  // [m].
  Eigen::Vector3d inlier_centroid = Eigen::Vector3d::Zero();
  std::vector<cv::Point3f> inlier_points;  // per inlier, its model point (world) [m]
  size_t verified_slot = 0;                // the place's keyframe holding most inliers
  double rotation_deg = 0.0;               // from the verified keyframe's view
  int cells = 0;                           // of a 4x4 grid holding an inlier
  int required_cells = 0;                  // RequiredInlierCells for the photo
  // The view check, made on a pose of min_inliers or more, whatever the other checks said.
  ViewAgreement agreement;
  bool looks_different = false;  // judged, and scored below min_view_agreement
  // Every check but the view check passed (and the pose is valid).
  bool passed_other_checks = false;
  // Accepted by the other checks, not judged, and fewer inliers than min_inliers_unchecked: a weak
  // pose nothing confirms.
  bool unconfirmed = false;
  // Its inliers lie on the ceiling alone (RestsOnCeilingOnly): refused, and nobody's rival.
  bool ceiling_only = false;
  bool accepted = false;  // valid and every check passed
  // Verified from the winner's pose moved by a copy offset (CopyOffsets): a copy of what the
  // winner matched elsewhere.
  bool copy = false;
};
// PnP RANSAC for each intrinsics candidate (with the focal refined when estimated), the best
// grown by guided matching, then the checks: min_inliers, the paper's 90 deg from the keyframe
// the inliers came from, min_inlier_cells, min_inlier_share of the projected points, and last
// min_view_agreement against that keyframe's thumbnail (when it has one; a pose under
// min_inliers_unchecked inliers the check cannot judge is refused). The view check is measured
// on every pose of min_inliers, one the other checks refused too: Decide asks it of rivals.
PlaceVerdict VerifyPlace(const PreparedPhoto& photo, const Place& place,
                         const PlaceMatches& matches, const std::vector<LocatorKeyframe>& keyframes,
                         const LocatorOptions& options);
// Stage 5d, when no place's pose was accepted: a pose refused by the view check alone is judged
// again against the keyframes of its place standing near it (view_second_opinion), their pixels
// projected together (MeasureViewAgreement over several). The verified keyframe may have seen its
// view past furniture that stands between the photo and the wall (a quarter of photos are taken
// with something in the way); a keyframe from nearer the photo's standpoint shows that furniture
// where the photo does. Accepts the verdict when that scores min_view_agreement; whether it did.
bool JudgeViewAgain(const PreparedPhoto& photo, const Place& place,
                    const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options,
                    PlaceVerdict* verdict);
// JudgeViewAgain for each of `verdicts` (verdicts[i] verified against places[i]) when none of
// them was accepted; nothing when one was: a pose the view check refused beside an accepted one
// only competes with it (on 1,200 session-2 photos, two of those so accepted were wrong answers).
void JudgeViewsAgain(const PreparedPhoto& photo, const std::vector<Place>& places,
                     const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options,
                     std::vector<PlaceVerdict>* verdicts);
// The keyframes JudgeViewAgain compares: the verified one, then up to
// view_second_opinion.keyframes of the place's others with thumbnails standing within
// view_second_opinion.radius_m of the pose and looking within view_second_opinion.max_angle_deg
// of it, nearest first (slots).
std::vector<size_t> SecondOpinionKeyframes(const PlaceVerdict& verdict, const Place& place,
                                           const std::vector<LocatorKeyframe>& keyframes,
                                           const LocatorOptions& options);

// The cells of the 4x4 grid a pose's inliers must cover in this photo: min_inlier_cells, or half
// the photo's detail cells when that is fewer, but at least min_inlier_cells_few_detail.
int RequiredInlierCells(const PreparedPhoto& photo, const LocatorOptions& options);
// Whether a verdict's inliers are fewer than min_inlier_share of the place's points its pose
// projects into the photo (one of VerifyPlace's checks).
bool HasLowInlierShare(const PlaceVerdict& verdict, const LocatorOptions& options);
// Whether a verdict's inliers lie on the ceiling alone: 80% of them (the 10th to the 90th
// percentile of their heights along `world_up`) within ceiling_only_max_thickness_m, and all of
// those above its camera. The model's up comes from its keyframes (EstimateWorldUp).
bool RestsOnCeilingOnly(const PlaceVerdict& verdict, const Eigen::Vector3d& world_up,
                        const LocatorOptions& options);

// Stage 5b: places that may be the winner's twin. The model repeats itself (identical desks, the
// same box in two rooms), and a photo of one copy verifies against the other; the search stops at
// the first confident place and retrieval ranks by the photo's words, so the other copy may never
// be verified. The winner's inliers' model descriptors, as a query (RetrieveCandidates), rank the
// keyframes that look like what the photo matched: `look_alikes`. Those whose descriptor matches
// with the winner's verified keyframe (at least twin_min_matches) mostly join different 3D points
// (SharedPointShare below twin_max_shared_share) look like it without looking at the same things:
// they are grouped as GroupPlaces does, at most twin_places places (none already in a place tried),
// to be verified against the photo and decided with the rest. A twin that fits about as well makes
// the photo ambiguous; one that fits better wins.
std::vector<Place> TwinPlaces(const std::vector<slam::PlaceCandidate>& look_alikes,
                              size_t verified_slot, const std::vector<Place>& tried,
                              const std::vector<LocatorKeyframe>& keyframes,
                              const LocatorOptions& options);

// Of a's descriptors matched to b's (nearest within max_descriptor_distance or sift_max_distance,
// passing match_ratio against the second nearest), the share whose 3D points lie within
// same_pose_m of each other:
// near 1 for two views of the same things, near 0 for views of identical things elsewhere.
// `matches` receives the number of matches.
double SharedPointShare(const LocatorKeyframe& a, const LocatorKeyframe& b,
                        const LocatorOptions& options, int* matches);

// Stage 5c: copies of what the winner matched, moved along the building (the same desk twice in
// a row, 2.2 m apart). TwinPlaces finds a copy only where a keyframe saw it from about where the
// winner's keyframe saw the original; a photo of a copy the walk passed at another angle verifies
// against the original, a copy's width off, and nothing contradicts it. The winner's inliers'
// model descriptors (at most copies.max_voters of them) are matched (nearest two within
// guided_max_distance, or sift_guided_max_distance) to the `searched` keyframes' features; each
// match to a point more than same_pose_m away votes for the offset between the two points. An
// offset with votes from at least copies.min_support of the winner's inliers within
// copies.cluster_m of it is a copy, refined to the median of those votes; its votes are then set
// aside and the next is sought, up to copies.offsets copies, most support first. Copies turned
// against the original (mirrored rooms) are not found here: TwinPlaces and the view check answer
// for those.
struct CopyOffset {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // the copy's points minus the original's [m]
  int support = 0;                                   // the winner's inliers voting for it
};
std::vector<CopyOffset> CopyOffsets(const PlaceVerdict& winner, const std::vector<size_t>& searched,
                                    const std::vector<LocatorKeyframe>& keyframes,
                                    const LocatorOptions& options);

// The keyframes CopyOffsets searches besides the look-alikes: copies along a room are seen from
// every side the walk passed, most of them unlike the winner's view. Of the real keyframes (not
// synthetic views, which crowd round the appliances) with points within copies.around_m of
// `centre` (the winner's inliers') and not in `skip`, up to
// copies.around_keyframes spread farthest-first over position and view direction (a radian
// counting as a metre), from the one nearest the centre.
std::vector<size_t> KeyframesAround(const Eigen::Vector3d& centre, const std::vector<size_t>& skip,
                                    const std::vector<LocatorKeyframe>& keyframes,
                                    const LocatorOptions& options);

// The real keyframes (a copy is judged by the view check, which needs their thumbnails) that
// see `target` from near a pose: within copies.place_radius_m of
// `world_from_cam`, looking within place_max_angle_deg of it, holding at least min_inliers points
// within neighbour_radius_m of `target`; the max_neighbours + 1 holding most, the head first. An
// empty place when none does.
Place PlaceSeeing(const Eigen::Isometry3d& world_from_cam, const Eigen::Vector3d& target,
                  const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options);

// Stage 4 from a rough pose (a copy's): the place's 3D points projected with `pose` each take the
// nearest-descriptor photo keypoint within copies.search_radius_px (if within guided_max_distance),
// the correspondences VerifyPlace then fits a pose to.
PlaceMatches MatchPlaceFrom(const PreparedPhoto& photo, const Place& place,
                            const std::vector<LocatorKeyframe>& keyframes,
                            const PoseHypothesis& pose, const LocatorOptions& options);

// How firmly a pose's inliers fix it: the covariance of (the camera centre in the world [m], a
// turn of the camera about its own axes [rad]) from the reprojection Jacobian at the pose, each
// inlier weighted by a pixel of keypoint noise and its model point's depth noise (the sensor's
// axial noise at its distance, seen across the photo's ray). False when the inliers do not fix
// the pose (fewer than three, collinear).
bool PoseCovariance(const std::vector<cv::Point3f>& world_points,
                    const Eigen::Isometry3d& world_from_cam, const Intrinsics& intrinsics,
                    Eigen::Matrix<double, 6, 6>* covariance);

// Stage 5e: LocatorOptions::slide for an accepted winner verified against `place`. Along the
// major axis of its position's spread (PoseCovariance of its inlier points), the camera moved
// with the turn that keeps those inliers in place (the rotation's regression on the position),
// each step grown by guided matching and refined. The pose so found, or nothing when no step
// gained.
std::optional<PoseHypothesis> SlideAlongWeakAxis(const PreparedPhoto& photo, const Place& place,
                                                 const std::vector<LocatorKeyframe>& keyframes,
                                                 const PlaceVerdict& winner,
                                                 const LocatorOptions& options);

// Stage 6: the answer from the verdicts, in the order the places were tried. The accepted
// verdict with most inliers wins unless the disagreeing pose with most inliers (more than
// same_pose_m or same_pose_deg away, accepted or refused with min_inliers, but not one whose view
// looked different from the photo) has more than
// 1 / min_inlier_ratio_over_runner_up of its inliers, or explains nearly the same part of the
// photo with other things (less than min_unique_inlier_share of the winner's inliers lie in cells
// of the 8x8 grid the runner-up's leave empty, and the two inlier centroids lie more than
// same_pose_m apart: a copy elsewhere, not the same things seen with another focal length): then
// the photo is ambiguous. Among poses with about as many inliers, the one whose view check leads
// every other placed elsewhere by ambiguity_min_agreement_lead wins instead (a rival only when
// accepted). Last, an answer is ambiguous when a pose elsewhere the view check refused, scoring
// at least ambiguity_min_doubted_agreement, has min_inlier_ratio_over_runner_up x its inliers.
// Copies (PlaceVerdict::copy) are decided apart: DecideAmongCopies.
struct Decision {
  int winner = -1;  // index into the verdicts, -1 when not matched
  int runner_up_inliers = 0;
  Eigen::Isometry3d runner_up_pose = Eigen::Isometry3d::Identity();
  std::optional<Refusal> refusal;  // when not matched: ambiguous, unseen view, few matches, ...
  // When ambiguous: the two verdicts that fit about as well (indices into the verdicts), the
  // leader first: the one of most inliers, between copies the one the view check scored higher,
  // and against a stronger pose the view check half refused, the accepted one.
  std::vector<int> ambiguous;
};
Decision Decide(const std::vector<PlaceVerdict>& verdicts, const LocatorOptions& options);
// The part of Decide for copies: when accepted verdicts disagree with the one of most inliers
// (verdicts[best_index]) and either is a copy's, inlier counts say only which copy the walk saw
// better from the photo's side; their surroundings tell them apart. The one whose view check scored
// highest wins when it leads every other by copies.min_agreement_lead, else the photo is ambiguous;
// nullopt without such rivals.
std::optional<Decision> DecideAmongCopies(const std::vector<PlaceVerdict>& verdicts,
                                          size_t best_index, const LocatorOptions& options);

// Stage 7 for a photo not matched: when matching failed (an unknown place, an unseen view, few
// matches, matches in one corner, a view unlike the photo) on a photo whose features fill at most
// bare_view_max_detail_cells of the 4x4 grid, the answer is that it shows too little (kBareView,
// the matcher's reason kept after it): what to do is to include more of the room. An ambiguous,
// empty or featureless photo keeps its reason.
Refusal ExplainBareView(Refusal refusal, int photo_detail_cells, const LocatorOptions& options);

// For a photo Decide refused: the verdict the answer would have been (an ambiguous photo's
// accepted winner, else the refused pose with most inliers), to tell right refusals from wrong
// ones; null when no place gave a pose.
const PlaceVerdict* WouldBeAnswer(const std::vector<PlaceVerdict>& verdicts);

}  // namespace sightmap::identify
