#include "identify/locator.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <future>
#include <mutex>
#include <optional>
#include <sstream>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "identify/coverage.h"
#include "identify/locate_stages.h"
#include "identify/visibility.h"
#include "slam/place_index.h"
#include "slam/vocabulary.h"
#include "slam/vote_index.h"

namespace sightmap::identify {

bool LocatorOptions::Check(std::string* error) const {
  std::ostringstream why;
  if (!slam::CheckOrbFeatures(features, error)) return false;
  if (!sift_features.Check(error) || !sift_photo_features.Check(error)) return false;
  if (max_image_side_px < 320)
    why << "max_image_side_px must be at least 320";
  else if (sift_features.type != slam::FeatureOptions::Type::kSift ||
           sift_photo_features.type != slam::FeatureOptions::Type::kSift)
    why << "sift_features and sift_photo_features must be of type \"sift\"";
  else if (sift_image_side_px < 320)
    why << "sift_image_side_px must be at least 320";
  else if (!(sift_max_distance > 0.0) || !(sift_guided_max_distance > 0.0))
    why << "sift_max_distance and sift_guided_max_distance must be positive";
  else if (second_look_max_places < 1)
    why << "second_look_max_places must be positive";
  else if (vlad.candidates < 1)
    why << "vlad.candidates must be positive";
  else if (!vlad.codebook.Check(error))
    return false;
  else if (place_threads < 0)
    why << "place_threads must not be negative";
  else if (retrieval_candidates < 1 || reserve_candidates < 0)
    why << "retrieval_candidates must be at least 1, reserve_candidates not negative";
  else if (vote_shortlist < 1 || vote_max_hamming < 0 || vote_max_hamming > 256)
    why << "vote_shortlist must be positive, vote_max_hamming in [0, 256]";
  else if (wide_vote_shortlist < 0 ||
           (wide_vote_shortlist > 0 && wide_vote_shortlist <= vote_shortlist))
    why << "wide_vote_shortlist must exceed vote_shortlist (" << vote_shortlist
        << "), or be 0 to turn the second search off";
  else if (neighbour_radius_m < 0.0 || max_neighbours < 0)
    why << "neighbour_radius_m and max_neighbours must not be negative";
  else if (match_node_level < 0)
    why << "match_node_level must not be negative";
  else if (!(match_ratio > 0.0 && match_ratio <= 1.0))
    why << "match_ratio must be in (0, 1]";
  else if (same_point_m < 0.0)
    why << "same_point_m must not be negative";
  else if (max_descriptor_distance < 1)
    why << "max_descriptor_distance must be positive";
  else if (!(pnp_reprojection_px > 0.0) || pnp_iterations < 1)
    why << "pnp_reprojection_px and pnp_iterations must be positive";
  else if (min_inliers < 4)
    why << "min_inliers must be at least 4 (PnP needs 4 points)";
  else if (confident_inliers < min_inliers)
    why << "confident_inliers must be at least min_inliers";
  else if (twin_places < 0 || twin_min_matches < 1 ||
           !(twin_max_shared_share >= 0.0 && twin_max_shared_share <= 1.0))
    why << "twin_places must not be negative, twin_min_matches positive, twin_max_shared_share "
           "in [0, 1]";
  else if (slide.min_sd_m < 0.0 || !(slide.max_sd_m > slide.min_sd_m) || !(slide.reach_sd > 0.0) ||
           !(slide.reach_m > 0.0) || slide.steps < 1 || slide.rounds < 1 || slide.min_gain < 0)
    why << "slide needs 0 <= min_sd_m < max_sd_m, positive reach_sd, reach_m, steps and rounds, "
           "and min_gain >= 0";
  else if (copies.offsets < 0 || copies.look_alikes < 0 || copies.around_keyframes < 0 ||
           !(copies.around_m > 0.0) || copies.max_voters < 1 || !(copies.cluster_m > 0.0) ||
           copies.min_support < 3 || !(copies.place_radius_m > 0.0) ||
           !(copies.search_radius_px > 0.0) || !(copies.min_agreement_lead >= 0.0))
    why << "copies: offsets, look_alikes, around_keyframes and min_agreement_lead must not be "
           "negative, around_m, max_voters, cluster_m, place_radius_m and search_radius_px "
           "positive, min_support at least 3";
  else if (!(max_rotation_from_keyframe_deg > 0.0 && max_rotation_from_keyframe_deg <= 180.0))
    why << "max_rotation_from_keyframe_deg must be in (0, 180]";
  else if (!(place_radius_m >= 0.0) || !(place_max_angle_deg >= 0.0) || max_places < 1)
    why << "place_radius_m and place_max_angle_deg must not be negative, max_places positive";
  else if (min_ransac_inliers < 4 || !(guided_radius_px > 0.0) || guided_max_distance < 1 ||
           guided_rounds < 0)
    why << "min_ransac_inliers must be at least 4, guided_radius_px and guided_max_distance "
           "positive, guided_rounds not negative";
  else if (min_inlier_cells < 0 || min_inlier_cells > 16 || min_inlier_cells_few_detail < 0 ||
           min_inlier_cells_few_detail > 16)
    why << "min_inlier_cells and min_inlier_cells_few_detail must be in [0, 16]";
  else if (bare_view_max_detail_cells < 0 || bare_view_max_detail_cells > 16)
    why << "bare_view_max_detail_cells must be in [0, 16]";
  else if (!(min_inlier_share >= 0.0 && min_inlier_share <= 1.0))
    why << "min_inlier_share must be in [0, 1]";
  else if (!(ceiling_only_max_thickness_m >= 0.0 && ceiling_only_max_thickness_m <= 1.0))
    why << "ceiling_only_max_thickness_m must be in [0, 1] m";
  else if (!(same_pose_m >= 0.0) || !(same_pose_deg >= 0.0) ||
           !(min_inlier_ratio_over_runner_up >= 1.0) ||
           !(min_unique_inlier_share >= 0.0 && min_unique_inlier_share <= 1.0) ||
           !(ambiguity_min_agreement_lead >= 0.0 && ambiguity_min_agreement_lead <= 1.0) ||
           !(ambiguity_min_doubted_agreement >= 0.0 && ambiguity_min_doubted_agreement <= 1.0))
    why << "same_pose_m and same_pose_deg must not be negative, "
           "min_inlier_ratio_over_runner_up at least 1, min_unique_inlier_share, "
           "ambiguity_min_agreement_lead and ambiguity_min_doubted_agreement in [0, 1]";
  else if (focal_candidates_35mm.empty())
    why << "focal_candidates_35mm must not be empty";
  else if (!(occlusion_voxel_m > 0.0) || occlusion_downscale < 1 || occlusion_pixel_step < 1 ||
           !(occlusion_max_depth_m > 0.0))
    why << "occlusion_voxel_m, occlusion_downscale, occlusion_pixel_step and "
           "occlusion_max_depth_m must be positive";
  else if (occlusion_max_hole_px < 0)
    why << "occlusion_max_hole_px must not be negative";
  else if (occlusion_margin_m < 0.0 || occlusion_margin_ratio < 0.0 ||
           occlusion_own_surface_m < 0.0)
    why << "occlusion margins and occlusion_own_surface_m must not be negative";
  else if (!(min_view_agreement >= 0.0 && min_view_agreement <= 1.0) || min_inliers_unchecked < 0 ||
           second_look_min_inliers_unchecked < 0)
    why << "min_view_agreement must be in [0, 1], min_inliers_unchecked and "
           "second_look_min_inliers_unchecked not negative";
  else if (view_second_opinion.keyframes < 0 || !(view_second_opinion.radius_m > 0.0) ||
           !(view_second_opinion.max_angle_deg > 0.0 && view_second_opinion.max_angle_deg <= 180.0))
    why << "view_second_opinion needs keyframes not negative, radius_m positive and "
           "max_angle_deg in (0, 180]";
  else if (!view_agreement.Check(error))
    return false;
  else if (!(min_in_view_share > 0.0 && min_in_view_share <= 1.0) ||
           !(min_unoccluded_share > 0.0 && min_unoccluded_share <= 1.0))
    why << "min_in_view_share and min_unoccluded_share must be in (0, 1]";
  for (double f : focal_candidates_35mm) {
    if (why.tellp() == 0 && !(f > 0.0)) why << "focal_candidates_35mm must be positive";
  }
  if (why.tellp() == 0) return true;
  if (error != nullptr) *error = "LocatorOptions: " + why.str();
  return false;
}

namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The keyframes' RootSIFT (a synthetic view's slot has none) indexed by slot for the second look,
// with a codebook trained on them; empty when no keyframe has enough to train on.
slam::VladIndex IndexRootSift(const std::vector<LocatorKeyframe>& sift_keyframes,
                              const slam::VladOptions& options) {
  std::vector<cv::Mat> descriptors;
  for (const LocatorKeyframe& keyframe : sift_keyframes)
    descriptors.push_back(keyframe.descriptors);
  if (slam::VladIndex::SampledRows(descriptors, options) < static_cast<size_t>(options.centres)) {
    return {};
  }
  slam::VladIndex index = slam::VladIndex::Train(descriptors, options);
  for (size_t slot = 0; slot < descriptors.size(); ++slot) {
    index.Add(static_cast<int64_t>(slot), descriptors[slot]);
  }
  return index;
}

// The keyframe as the view check compares it, from its grey image decoded at the smallest scale
// at least as wide as the thumbnail; null with the check off or without a colour image and depth
// of the keyframe's size.
std::shared_ptr<const KeyframeThumbnail> LoadThumbnail(const store::Model& model,
                                                       const store::KeyframeInfo& info,
                                                       const cv::Mat& depth,
                                                       const LocatorOptions& options) {
  if (!(options.min_view_agreement > 0.0) || info.color_bytes <= 0 || depth.empty() ||
      depth.cols != info.intrinsics.width || depth.rows != info.intrinsics.height) {
    return nullptr;
  }
  int reduction = 8;
  while (reduction > 1 && depth.cols / reduction < options.view_agreement.thumbnail_width_px) {
    reduction /= 2;
  }
  return std::make_shared<const KeyframeThumbnail>(MakeThumbnail(
      model.LoadGrey(info.id, reduction), depth, info.intrinsics, options.view_agreement));
}

struct TimedSiftPhoto {
  PreparedPhoto photo;
  double ms = 0.0;  // the extraction's own time, on whichever thread ran it
};

TimedSiftPhoto ExtractRootSiftTimed(const cv::Mat& photo, const PreparedPhoto& seed,
                                    const LocatorOptions& options) {
  const Clock::time_point start = Clock::now();
  TimedSiftPhoto timed;
  timed.photo = RootSiftPhoto(photo, seed, options);
  timed.ms = MsSince(start);
  return timed;
}

VisibilityOptions ToVisibilityOptions(const LocatorOptions& options) {
  VisibilityOptions v;
  v.zbuffer_downscale = options.occlusion_downscale;
  v.margin_m = options.occlusion_margin_m;
  v.margin_ratio = options.occlusion_margin_ratio;
  v.behind_needs_own_surface = options.occlusion_behind_needs_surface;
  v.own_surface_m = options.occlusion_own_surface_m;
  v.min_in_view_share = options.min_in_view_share;
  v.min_unoccluded_share = options.min_unoccluded_share;
  return v;
}

// The photo verified with the one camera `intrinsics` (a winner's: the photo was taken with one).
PreparedPhoto WithCamera(const PreparedPhoto& photo, const Intrinsics& intrinsics) {
  PreparedPhoto same_camera = photo;
  same_camera.feature_candidates = {intrinsics};
  same_camera.intrinsics_given = true;
  return same_camera;
}

// A decision that answers the photo: a pose, or two places that fit about as well.
bool Answered(const Decision& decision) {
  return decision.winner >= 0 ||
         (decision.refusal && decision.refusal->code == UnmatchedReason::kAmbiguous);
}

// Whether the two rankings hold the same keyframes (in any order).
bool SameCandidates(const std::vector<slam::PlaceCandidate>& a,
                    const std::vector<slam::PlaceCandidate>& b) {
  if (a.size() != b.size()) return false;
  std::vector<int64_t> ids_a;
  std::vector<int64_t> ids_b;
  for (const slam::PlaceCandidate& c : a) ids_a.push_back(c.id);
  for (const slam::PlaceCandidate& c : b) ids_b.push_back(c.id);
  std::sort(ids_a.begin(), ids_a.end());
  std::sort(ids_b.begin(), ids_b.end());
  return ids_a == ids_b;
}

}  // namespace

struct Locator::Impl {
  LocatorOptions options;
  // `options` with the second look's min_inliers_unchecked, for verifying against sift_keyframes.
  LocatorOptions second_look_options;
  std::vector<LocatorKeyframe> keyframes;  // ORB's
  // The same slots with RootSIFT features (synthetic views without any); empty with the ORB
  // matcher.
  std::vector<LocatorKeyframe> sift_keyframes;
  slam::Vocabulary vocabulary;
  // Ids are slots into `keyframes`: every keyframe's bag of words (photos' retrieval with
  // LocatorOptions::Retrieval::kBagOfWords, and the twin check's) and descriptors (with kVotes).
  slam::PlaceIndex index;
  slam::VoteIndex votes;
  // Over sift_keyframes' RootSIFT, by slot; empty unless second_look_retrieval is vlad.
  slam::VladIndex vlad;
  size_t num_synthetic_views = 0;  // the last ones of `keyframes`
  // The model's up (EstimateWorldUp of its keyframes), for RestsOnCeilingOnly.
  Eigen::Vector3d world_up = Eigen::Vector3d::UnitZ();
  size_t num_sift_extracted = 0;
  OcclusionCloud cloud;
  // Every keyframe's depth at 80x60, to tell from which side the walk saw each label point.
  std::vector<SightingView> sighting_views;
  struct LabelSet {
    std::vector<store::LabelRecord> labels;
    LabelSightings sightings;  // per label, per point
  };
  mutable std::mutex labels_mutex;
  std::shared_ptr<const LabelSet> labels;

  std::shared_ptr<const LabelSet> CurrentLabels() const {
    std::lock_guard<std::mutex> lock(labels_mutex);
    return labels;
  }

  // The keyframes that look like what the winner matched: its inliers' model descriptors (a
  // RootSIFT winner's keyframe's ORB features) ranked by bag of words.
  std::vector<slam::PlaceCandidate> LookAlikes(const PlaceVerdict& winner,
                                               const std::vector<LocatorKeyframe>& matched) const;
  // Stage 5b strung together: the places elsewhere that look like the winner's verified keyframe
  // (TwinPlaces), each matched and verified against `photo` (prepared with the winner's camera
  // only: the photo was taken with one). Their verdicts, for Decide with the rest.
  std::vector<PlaceVerdict> VerifyTwins(const PreparedPhoto& photo, const PlaceVerdict& winner,
                                        const std::vector<slam::PlaceCandidate>& look_alikes,
                                        const std::vector<Place>& tried,
                                        const std::vector<LocatorKeyframe>& matched,
                                        LocateTimings* timings) const;
  // Stage 5c strung together: the winner's pose moved by each copy offset (CopyOffsets), matched
  // from there against the keyframes that see the copy (PlaceSeeing, MatchPlaceFrom) and verified
  // against `photo` (as VerifyTwins'). Their verdicts, for Decide with the rest.
  std::vector<PlaceVerdict> VerifyCopies(const PreparedPhoto& photo, const PlaceVerdict& winner,
                                         const std::vector<slam::PlaceCandidate>& look_alikes,
                                         const std::vector<LocatorKeyframe>& matched,
                                         LocateTimings* timings) const;

  // The labelled appliances in view from a pose (the photo's intrinsics at its full size).
  std::vector<ApplianceInView> AppliancesSeenFrom(const Eigen::Isometry3d& world_from_cam,
                                                  const Intrinsics& intrinsics) const {
    const auto current = CurrentLabels();
    return AppliancesInView(current->labels, &cloud, intrinsics, world_from_cam,
                            ToVisibilityOptions(options), &current->sightings);
  }
  // The places an ambiguous decision names (Decision::ambiguous, empty otherwise), each with what
  // is in view from it. `photo_size` is the photo's full size.
  std::vector<PossiblePlace> PossiblePlaces(const std::vector<PlaceVerdict>& verdicts,
                                            const Decision& decision,
                                            const std::vector<LocatorKeyframe>& matched,
                                            const cv::Size& photo_size) const {
    std::vector<PossiblePlace> places;
    for (const int v : decision.ambiguous) {
      const PlaceVerdict& verdict = verdicts[static_cast<size_t>(v)];
      PossiblePlace place;
      place.world_from_cam = verdict.pose.world_from_cam;
      place.inliers = verdict.inliers;
      place.keyframe = matched[verdict.verified_slot].id;
      place.appliances =
          AppliancesSeenFrom(place.world_from_cam,
                             verdict.pose.intrinsics.Scaled(photo_size.width, photo_size.height));
      places.push_back(std::move(place));
    }
    return places;
  }

  // The options a pose verified against `matched` is checked and decided with: the second
  // look's when `matched` is sift_keyframes.
  const LocatorOptions& VerifyingOptions(const std::vector<LocatorKeyframe>& matched) const {
    return &matched == &sift_keyframes ? second_look_options : options;
  }

  // Stages 3-6 for one matcher: the candidates grouped into places (those from `reserve_from` on
  // as GroupPlaces' reserve), each matched against `matched` (keyframes or sift_keyframes) and
  // verified until one is certain, the twin check, the decision.
  struct Search {
    std::vector<PlaceVerdict> verdicts;
    Decision decision;
  };
  Search SearchPlaces(PreparedPhoto* photo, const std::vector<slam::PlaceCandidate>& candidates,
                      size_t reserve_from, const std::vector<LocatorKeyframe>& matched,
                      int max_places, LocateTimings* timings,
                      const std::function<void()>& first_refused = {}) const;

  // Stage 3-6 again with RootSIFT, for a photo ORB could not place: the photo's RootSIFT
  // (`sift`) matched against sift_keyframes at the same candidates (after VLAD's with
  // second_look_retrieval vlad), at most second_look_max_places. Its search when it placed the
  // photo or found it ambiguous, else nothing (ORB's refusal stands). Times and the second
  // look's flags go to `result`.
  std::optional<Search> SecondLook(const PreparedPhoto& sift,
                                   const std::vector<slam::PlaceCandidate>& candidates,
                                   LocateResult* result) const;

  // LocatorOptions::slide for the search's winner among `places` (verdicts[i] verified against
  // places[i]): its pose slid along its spread (SlideAlongWeakAxis), verified again with the
  // winner's camera, replaces it when accepted with slide.min_gain more inliers, and the search
  // is decided again.
  void SlideWinner(const PreparedPhoto& photo, const std::vector<Place>& places,
                   const std::vector<LocatorKeyframe>& matched, Search* search,
                   LocateTimings* timings) const;
  // VerifyPlace, then the check that needs the model's up (RestsOnCeilingOnly).
  PlaceVerdict Verify(const PreparedPhoto& photo, const Place& place, const PlaceMatches& matches,
                      const std::vector<LocatorKeyframe>& matched) const;
  // Stages 3-4 over `places`, place_threads at a time; with `until_certain`, in order until one
  // is certain (accepted with confident_inliers), the first alone. Their verdicts in order, none
  // after the certain one: the same whatever the thread count. Matching and PnP times are summed
  // over the places, so with threads they may exceed the wall time.
  // `first_refused` (may be empty) is called when the first place's verdict refuses the photo.
  std::vector<PlaceVerdict> VerifyPlaces(const PreparedPhoto& photo,
                                         const std::vector<Place>& places,
                                         const std::vector<LocatorKeyframe>& matched,
                                         bool until_certain, LocateTimings* timings,
                                         const std::function<void()>& first_refused = {}) const;
};

PlaceVerdict Locator::Impl::Verify(const PreparedPhoto& photo, const Place& place,
                                   const PlaceMatches& matches,
                                   const std::vector<LocatorKeyframe>& matched) const {
  PlaceVerdict verdict = VerifyPlace(photo, place, matches, matched, VerifyingOptions(matched));
  if (RestsOnCeilingOnly(verdict, world_up, options)) {
    verdict.ceiling_only = true;
    verdict.accepted = false;
  }
  return verdict;
}

void Locator::Impl::SlideWinner(const PreparedPhoto& photo, const std::vector<Place>& places,
                                const std::vector<LocatorKeyframe>& matched, Search* search,
                                LocateTimings* timings) const {
  const int winner_index = search->decision.winner;
  if (options.slide.min_sd_m <= 0.0 || winner_index < 0 ||
      static_cast<size_t>(winner_index) >= places.size()) {
    return;
  }
  const Clock::time_point stage = Clock::now();
  PlaceVerdict& winner = search->verdicts[static_cast<size_t>(winner_index)];
  const Place& place = places[static_cast<size_t>(winner_index)];
  const std::optional<PoseHypothesis> slid =
      SlideAlongWeakAxis(photo, place, matched, winner, options);
  if (slid) {
    const PreparedPhoto same_camera = WithCamera(photo, winner.pose.intrinsics);
    PlaceVerdict again = Verify(
        same_camera, place, MatchPlaceFrom(same_camera, place, matched, *slid, options), matched);
    if (again.accepted && again.inliers >= winner.inliers + options.slide.min_gain) {
      winner = std::move(again);
      search->decision = Decide(search->verdicts, VerifyingOptions(matched));
    }
  }
  timings->pnp_ms += MsSince(stage);
}

std::vector<PlaceVerdict> Locator::Impl::VerifyPlaces(
    const PreparedPhoto& photo, const std::vector<Place>& places,
    const std::vector<LocatorKeyframe>& matched, bool until_certain, LocateTimings* timings,
    const std::function<void()>& first_refused) const {
  const size_t threads = static_cast<size_t>(
      options.place_threads > 0 ? options.place_threads : std::max(1, cv::getNumThreads()));
  struct Slot {
    PlaceVerdict verdict;
    double matching_ms = 0.0;
    double pnp_ms = 0.0;
    std::exception_ptr error;
  };
  std::vector<PlaceVerdict> verdicts;
  for (size_t next = 0; next < places.size();) {
    const size_t batch = next == 0 && until_certain ? 1 : std::min(threads, places.size() - next);
    std::vector<Slot> slots(batch);
    const auto verify = [&](const cv::Range& range) {
      for (int i = range.start; i < range.end; ++i) {
        Slot& slot = slots[static_cast<size_t>(i)];
        const Place& place = places[next + static_cast<size_t>(i)];
        try {
          Clock::time_point stage = Clock::now();
          const PlaceMatches matches = MatchPlace(photo, place, matched, options);
          slot.matching_ms = MsSince(stage);
          stage = Clock::now();
          slot.verdict = Verify(photo, place, matches, matched);
          slot.pnp_ms = MsSince(stage);
        } catch (...) {
          slot.error = std::current_exception();
        }
      }
    };
    const cv::Range range(0, static_cast<int>(batch));
    if (batch == 1) {
      verify(range);
    } else {
      cv::parallel_for_(range, verify, static_cast<double>(batch));
    }
    for (Slot& slot : slots) {
      if (slot.error) std::rethrow_exception(slot.error);
      timings->matching_ms += slot.matching_ms;
      timings->pnp_ms += slot.pnp_ms;
      verdicts.push_back(std::move(slot.verdict));
      if (verdicts.size() == 1 && !verdicts.front().accepted && first_refused) first_refused();
      // A verified pose with this many inliers is certain: the remaining places would cost
      // their matching time for nothing.
      const PlaceVerdict& verdict = verdicts.back();
      if (until_certain && verdict.accepted && verdict.inliers >= options.confident_inliers) {
        return verdicts;
      }
    }
    next += batch;
  }
  return verdicts;
}

std::vector<slam::PlaceCandidate> Locator::Impl::LookAlikes(
    const PlaceVerdict& winner, const std::vector<LocatorKeyframe>& matched) const {
  // The vocabulary is ORB's: RootSIFT inliers ask with their keyframe's ORB features. Ranked by
  // bag of words whatever options.retrieval: the query is the model's own descriptors, not a
  // photo's, and on 200 session-2 photos votes found fewer twins (every keyframe ranked by votes
  // for the photos; hand-held seed 11 model: 107 matched, 4 wrong with votes here, 106 and 3 with
  // bag of words; survey 136 and 3, 137 and 3).
  const cv::Mat& query = &matched == &keyframes ? winner.inlier_descriptors
                                                : keyframes[winner.verified_slot].descriptors;
  return RetrieveCandidates(query, LocatorOptions::Retrieval::kBagOfWords,
                            options.retrieval_candidates, vocabulary, index, votes, keyframes,
                            options);
}

std::vector<PlaceVerdict> Locator::Impl::VerifyTwins(
    const PreparedPhoto& photo, const PlaceVerdict& winner,
    const std::vector<slam::PlaceCandidate>& look_alikes, const std::vector<Place>& tried,
    const std::vector<LocatorKeyframe>& matched, LocateTimings* timings) const {
  const Clock::time_point stage = Clock::now();
  const std::vector<Place> twins =
      TwinPlaces(look_alikes, winner.verified_slot, tried, matched, options);
  timings->retrieval_ms += MsSince(stage);
  if (twins.empty()) return {};
  return VerifyPlaces(photo, twins, matched, /*until_certain=*/false, timings);
}

std::vector<PlaceVerdict> Locator::Impl::VerifyCopies(
    const PreparedPhoto& photo, const PlaceVerdict& winner,
    const std::vector<slam::PlaceCandidate>& look_alikes,
    const std::vector<LocatorKeyframe>& matched, LocateTimings* timings) const {
  Clock::time_point stage = Clock::now();
  // The first look-alikes and keyframes spread around the winner's things, each once; the
  // winner's own keyframe and its neighbours see the same points and vote for nothing.
  std::vector<size_t> own = matched[winner.verified_slot].neighbours;
  own.push_back(winner.verified_slot);
  std::vector<size_t> searched;
  for (const slam::PlaceCandidate& look_alike : look_alikes) {
    if (static_cast<int>(searched.size()) >= options.copies.look_alikes) break;
    const size_t slot = static_cast<size_t>(look_alike.id);
    if (std::find(own.begin(), own.end(), slot) == own.end()) searched.push_back(slot);
  }
  std::vector<size_t> skip = own;
  skip.insert(skip.end(), searched.begin(), searched.end());
  const std::vector<size_t> around =
      KeyframesAround(winner.inlier_centroid, skip, matched, options);
  searched.insert(searched.end(), around.begin(), around.end());
  const std::vector<CopyOffset> copies = CopyOffsets(winner, searched, matched, options);
  timings->matching_ms += MsSince(stage);
  std::vector<PlaceVerdict> verdicts;
  for (const CopyOffset& copy : copies) {
    stage = Clock::now();
    PoseHypothesis moved = winner.pose;
    moved.world_from_cam.pretranslate(copy.offset);
    moved.inliers.clear();
    const Place place =
        PlaceSeeing(moved.world_from_cam, winner.inlier_centroid + copy.offset, matched, options);
    if (place.slots.empty()) {
      timings->matching_ms += MsSince(stage);
      continue;
    }
    const PlaceMatches matches = MatchPlaceFrom(photo, place, matched, moved, options);
    timings->matching_ms += MsSince(stage);
    stage = Clock::now();
    verdicts.push_back(Verify(photo, place, matches, matched));
    verdicts.back().copy = true;
    timings->pnp_ms += MsSince(stage);
  }
  return verdicts;
}

Locator::Impl::Search Locator::Impl::SearchPlaces(
    PreparedPhoto* photo, const std::vector<slam::PlaceCandidate>& candidates, size_t reserve_from,
    const std::vector<LocatorKeyframe>& matched, int max_places, LocateTimings* timings,
    const std::function<void()>& first_refused) const {
  const std::vector<Place> places =
      GroupPlaces(candidates, reserve_from, max_places, matched, options);
  // Vocabulary nodes only for ORB matching bounded by them; exhaustive matching needs none.
  Clock::time_point stage = Clock::now();
  if (options.match_node_level > 0 && !vocabulary.empty() && &matched == &keyframes &&
      photo->nodes.empty()) {
    const cv::Mat& descriptors = photo->features.descriptors;
    for (int r = 0; r < descriptors.rows; ++r) {
      photo->nodes.push_back(
          vocabulary.NodeOf(descriptors.ptr<uint8_t>(r), options.match_node_level));
    }
  }
  timings->matching_ms += MsSince(stage);

  Search search;
  search.verdicts =
      VerifyPlaces(*photo, places, matched, /*until_certain=*/true, timings, first_refused);
  std::vector<PlaceVerdict>& verdicts = search.verdicts;
  stage = Clock::now();
  JudgeViewsAgain(*photo, places, matched, VerifyingOptions(matched), &verdicts);
  timings->pnp_ms += MsSince(stage);
  search.decision = Decide(verdicts, VerifyingOptions(matched));
  SlideWinner(*photo, places, matched, &search, timings);
  if (search.decision.winner < 0 || (options.twin_places <= 0 && options.copies.offsets <= 0)) {
    return search;
  }
  // The winner's look-alikes elsewhere: twins seen as the winner's keyframe saw it, and copies
  // moved along the building, verified against the photo with the winner's camera (it was taken
  // with one) and decided with the rest. The winner is copied: the verdicts grow below.
  const PlaceVerdict winner = verdicts[static_cast<size_t>(search.decision.winner)];
  const PreparedPhoto same_camera = WithCamera(*photo, winner.pose.intrinsics);
  const Clock::time_point looking = Clock::now();
  const std::vector<slam::PlaceCandidate> look_alikes = LookAlikes(winner, matched);
  timings->retrieval_ms += MsSince(looking);
  std::vector<PlaceVerdict> others;
  if (options.twin_places > 0) {
    const std::vector<Place> tried(places.begin(),
                                   places.begin() + static_cast<std::ptrdiff_t>(verdicts.size()));
    others = VerifyTwins(same_camera, winner, look_alikes, tried, matched, timings);
  }
  if (options.copies.offsets > 0) {
    std::vector<PlaceVerdict> copies =
        VerifyCopies(same_camera, winner, look_alikes, matched, timings);
    others.insert(others.end(), std::make_move_iterator(copies.begin()),
                  std::make_move_iterator(copies.end()));
  }
  if (!others.empty()) {
    verdicts.insert(verdicts.end(), std::make_move_iterator(others.begin()),
                    std::make_move_iterator(others.end()));
    search.decision = Decide(verdicts, VerifyingOptions(matched));
  }
  return search;
}

std::optional<Locator::Impl::Search> Locator::Impl::SecondLook(
    const PreparedPhoto& sift_photo, const std::vector<slam::PlaceCandidate>& candidates,
    LocateResult* result) const {
  const Clock::time_point start = Clock::now();
  result->second_look = true;
  std::optional<Search> answered;
  if (!sift_photo.refusal) {
    PreparedPhoto sift = sift_photo;
    // ORB's first candidates, after VLAD's when it ranks, then ORB's reserve.
    const auto first_end = candidates.begin() +
                           std::min<std::ptrdiff_t>(options.retrieval_candidates,
                                                    static_cast<std::ptrdiff_t>(candidates.size()));
    std::vector<slam::PlaceCandidate> tried(candidates.begin(), first_end);
    if (!vlad.empty()) {
      const Clock::time_point stage = Clock::now();
      tried = MergeCandidates(vlad.Rank(sift.features.descriptors, options.vlad.candidates), tried);
      result->timings.retrieval_ms += MsSince(stage);
    }
    const size_t reserve_from = tried.size();
    tried = MergeCandidates(tried, std::vector<slam::PlaceCandidate>(first_end, candidates.end()));
    Search again = SearchPlaces(&sift, tried, reserve_from, sift_keyframes,
                                options.second_look_max_places, &result->timings);
    if (Answered(again.decision)) {
      result->photo_features = static_cast<int>(sift.features.size());
      result->answered_by_second_look = true;
      answered = std::move(again);
    }
  }
  result->timings.second_look_ms += MsSince(start);
  return answered;
}

namespace {

// Descriptors the vocabulary and the matcher take: 32-byte binary (ORB) rows, at least one.
bool IsOrbDescriptors(const cv::Mat& descriptors) {
  return descriptors.rows > 0 && descriptors.type() == CV_8U && descriptors.cols == 32;
}

// The model's vocabulary; a model of fewer keyframes than the mapper trains its vocabulary on
// (a short recording) has none, and gets one trained here from its keyframes (empty when fewer
// than two have features: retrieval then tries every keyframe).
slam::Vocabulary LoadOrTrainVocabulary(const store::Model& model,
                                       const std::vector<store::KeyframeInfo>& infos) {
  const auto stored = model.LoadVocabulary();
  if (stored) {
    SIGHTMAP_CHECK(stored->first == slam::Vocabulary::kFormat,
                   "the model's vocabulary is in format '"
                       << stored->first << "', this sightmap reads '" << slam::Vocabulary::kFormat
                       << "'");
    return slam::Vocabulary::Deserialize(stored->second);
  }
  std::vector<cv::Mat> descriptors;
  for (const store::KeyframeInfo& info : infos) {
    const Features features = model.LoadFeatures(info.id);
    if (IsOrbDescriptors(features.descriptors)) descriptors.push_back(features.descriptors);
  }
  if (descriptors.size() < 2) return slam::Vocabulary();
  return slam::Vocabulary::Train(descriptors);
}

// A keyframe, real or synthetic, as the locator matches it: its features (ORB or RootSIFT) that
// have a 3D point, in the world.
LocatorKeyframe MakeLocatorKeyframe(KeyframeId id, const Eigen::Isometry3d& world_from_cam,
                                    const Features& features, const slam::Vocabulary& vocabulary,
                                    const LocatorOptions& options) {
  LocatorKeyframe keyframe;
  keyframe.id = id;
  keyframe.world_from_cam = world_from_cam;
  keyframe.view_direction = world_from_cam.linear().col(2);
  if (features.descriptors.empty() || features.descriptors.type() != CV_8U) return keyframe;
  const bool by_nodes =
      options.match_node_level > 0 && !vocabulary.empty() && IsOrbDescriptors(features.descriptors);
  std::vector<int> rows;
  for (size_t i = 0; i < features.points_cam.size(); ++i) {
    if (!features.has_point[i]) continue;
    rows.push_back(static_cast<int>(i));
    const Eigen::Vector3d world = world_from_cam * features.points_cam[i];
    keyframe.world_points.emplace_back(static_cast<float>(world.x()), static_cast<float>(world.y()),
                                       static_cast<float>(world.z()));
  }
  keyframe.descriptors.create(static_cast<int>(rows.size()), features.descriptors.cols, CV_8U);
  for (size_t r = 0; r < rows.size(); ++r) {
    features.descriptors.row(rows[r]).copyTo(keyframe.descriptors.row(static_cast<int>(r)));
    if (by_nodes) {
      keyframe.nodes.push_back(vocabulary.NodeOf(
          keyframe.descriptors.ptr<uint8_t>(static_cast<int>(r)), options.match_node_level));
    }
  }
  return keyframe;
}

// What retrieval keeps of a keyframe: its bag of words, and for the vote index every ORB
// descriptor (with or without a point) with its word.
struct RetrievalEntry {
  slam::BowVector bow;
  cv::Mat descriptors;  // both empty unless options.retrieval is kVotes
  std::vector<int> words;
};

// Nothing without a vocabulary (a model with one keyframe of features has none to index by) or
// ORB descriptors.
std::optional<RetrievalEntry> MakeRetrievalEntry(const Features& orb,
                                                 const slam::Vocabulary& vocabulary,
                                                 const LocatorOptions& options) {
  if (vocabulary.empty() || !IsOrbDescriptors(orb.descriptors)) return std::nullopt;
  const bool votes = options.retrieval == LocatorOptions::Retrieval::kVotes;
  RetrievalEntry entry;
  entry.bow = vocabulary.Transform(orb.descriptors, votes ? &entry.words : nullptr);
  if (votes) entry.descriptors = orb.descriptors;
  return entry;
}

// Adds the entry under `slot` to the bag-of-words index (the twin check's) and, with
// options.retrieval kVotes, to the vote index.
void IndexEntry(RetrievalEntry entry, size_t slot, const LocatorOptions& options,
                slam::PlaceIndex* index, slam::VoteIndex* votes) {
  if (options.retrieval == LocatorOptions::Retrieval::kVotes) {
    votes->Add(static_cast<int64_t>(slot), entry.descriptors, entry.words);
  }
  index->Add(static_cast<int64_t>(slot), std::move(entry.bow));
}

// A keyframe's RootSIFT features with their 3D points: those the model stores (`sightmap map`
// extracts them as it writes keyframes), else extracted from its stored colour and `depth` (the
// keyframe's, decoded by the caller, who needs it too) at the matcher's scale (a model mapped
// without them); none for a keyframe stored without images.
Features KeyframeSiftFeatures(const store::Model& model, const store::KeyframeInfo& info,
                              const cv::Mat& depth, const LocatorOptions& options, int* extracted) {
  if (std::optional<Features> stored = model.LoadPhotoFeatures(info.id)) {
    // An empty row: extracted when mapped, and nothing found.
    if (stored->size() == 0) return {};
    if (stored->descriptors.cols == 128 && stored->descriptors.type() == CV_8U) {
      return std::move(*stored);
    }
  }
  if (info.color_bytes <= 0 || depth.empty()) return {};
  const cv::Mat color = model.LoadColor(info.id);
  if (color.size() != depth.size()) return {};
  ++*extracted;
  return slam::ExtractFeaturesAtMostOfSide(color, depth, info.intrinsics,
                                           options.sift_image_side_px, options.sift_features);
}

// A keyframe as loaded, before it is indexed: its slots (MakeLocatorKeyframe, with the thumbnail
// for the view check), its retrieval entry, its depth at sighting size (its depth also went into
// the occlusion cloud). The features themselves are not kept: only what the locator holds.
struct LoadedKeyframe {
  bool has_orb = false;
  LocatorKeyframe orb;
  LocatorKeyframe sift;  // with_sift only
  std::optional<RetrievalEntry> retrieval;
  std::optional<SightingView> sighting;  // a keyframe with depth
  int sift_extracted = 0;                // 1: its RootSIFT was extracted here, not stored
};

LoadedKeyframe LoadKeyframe(const store::Model& model, const store::KeyframeInfo& info,
                            bool with_sift, const slam::Vocabulary& vocabulary,
                            const LocatorOptions& options, OcclusionCloudBuilder* cloud) {
  LoadedKeyframe loaded;
  const Features orb = model.LoadFeatures(info.id);
  loaded.has_orb = IsOrbDescriptors(orb.descriptors);
  loaded.retrieval = MakeRetrievalEntry(orb, vocabulary, options);
  loaded.orb = MakeLocatorKeyframe(info.id, info.world_from_cam, orb, vocabulary, options);
  const cv::Mat depth = info.depth_bytes > 0 ? model.LoadDepth(info.id) : cv::Mat();
  loaded.orb.thumbnail = LoadThumbnail(model, info, depth, options);
  if (with_sift) {
    loaded.sift = MakeLocatorKeyframe(
        info.id, info.world_from_cam,
        KeyframeSiftFeatures(model, info, depth, options, &loaded.sift_extracted), vocabulary,
        options);
    loaded.sift.thumbnail = loaded.orb.thumbnail;
  }
  if (!depth.empty()) {
    cloud->AddDepth(depth, info.intrinsics, info.world_from_cam, options.occlusion_pixel_step,
                    options.features.min_depth_m, options.occlusion_max_depth_m,
                    options.occlusion_max_hole_px);
    loaded.sighting = MakeSightingView(depth, info.intrinsics, info.world_from_cam, 80, 60);
  }
  return loaded;
}

// Every keyframe's LoadKeyframe, in order. Decoding the images and voxelising the depth are most
// of a large model's loading, so the later half loads on a second thread through its own
// read-only connection to the file (a connection serves one thread) into its own cloud, merged
// after; a model the file cannot be opened again for loads on the calling thread alone. Progress
// is reported from the calling thread only (LoadProgress).
std::vector<LoadedKeyframe> LoadKeyframes(const store::Model& model,
                                          const std::vector<store::KeyframeInfo>& infos,
                                          bool with_sift, const slam::Vocabulary& vocabulary,
                                          const LocatorOptions& options,
                                          OcclusionCloudBuilder* cloud,
                                          const LoadProgress& progress) {
  std::vector<LoadedKeyframe> loaded(infos.size());
  std::atomic<size_t> done{0};
  const auto report = [&] {
    if (progress) progress(done.load(), infos.size());
  };
  const auto load = [&](const store::Model& source, size_t begin, size_t end,
                        OcclusionCloudBuilder* into, bool reporting) {
    for (size_t i = begin; i < end; ++i) {
      loaded[i] = LoadKeyframe(source, infos[i], with_sift, vocabulary, options, into);
      ++done;
      if (reporting) report();
    }
  };
  std::optional<store::Model> second;
  if (infos.size() >= 2 && cv::getNumThreads() > 1) {
    try {
      second.emplace(store::Model::Open(model.path(), store::ModelOptions::ReadOnly()));
    } catch (const std::exception&) {
      // Left empty: the calling thread loads every keyframe.
    }
  }
  if (!second) {
    load(model, 0, infos.size(), cloud, /*reporting=*/true);
    return loaded;
  }
  const size_t half = infos.size() / 2;
  OcclusionCloudBuilder later_cloud(options.occlusion_voxel_m);
  // The future's destructor waits for the thread when this one throws first.
  std::future<void> later = std::async(std::launch::async, [&] {
    load(*second, half, infos.size(), &later_cloud, /*reporting=*/false);
  });
  load(model, 0, half, cloud, /*reporting=*/true);
  while (later.wait_for(std::chrono::milliseconds(200)) != std::future_status::ready) report();
  later.get();
  report();
  cloud->Merge(later_cloud);
  return loaded;
}

}  // namespace

Locator::Locator(const store::Model& model, const LocatorOptions& options,
                 const LoadProgress& progress)
    : impl_(std::make_unique<Impl>()) {
  SIGHTMAP_CHECK_OPTIONS(options);
  impl_->votes = slam::VoteIndex(options.vote_max_hamming);
  impl_->options = options;
  impl_->second_look_options = options;
  impl_->second_look_options.min_inliers_unchecked = options.second_look_min_inliers_unchecked;
  const std::vector<store::KeyframeInfo> infos = model.Keyframes();
  SIGHTMAP_CHECK(!infos.empty(), "the model " << model.path()
                                              << " has no keyframes: map a building into it "
                                                 "first ('sightmap map')");
  impl_->vocabulary = LoadOrTrainVocabulary(model, infos);
  impl_->world_up = EstimateWorldUp(infos);

  OcclusionCloudBuilder cloud(options.occlusion_voxel_m);
  bool any_orb_features = false;
  const bool with_sift = options.matcher != LocatorOptions::Matcher::kOrb;
  int sift_extracted = 0;  // keyframes the model stores no RootSIFT for
  std::vector<LoadedKeyframe> loaded =
      LoadKeyframes(model, infos, with_sift, impl_->vocabulary, options, &cloud, progress);
  impl_->keyframes.reserve(infos.size());
  for (LoadedKeyframe& keyframe : loaded) {
    any_orb_features = any_orb_features || keyframe.has_orb;
    if (keyframe.retrieval) {
      IndexEntry(std::move(*keyframe.retrieval), impl_->keyframes.size(), options, &impl_->index,
                 &impl_->votes);
    }
    impl_->keyframes.push_back(std::move(keyframe.orb));
    if (with_sift) {
      impl_->sift_keyframes.push_back(std::move(keyframe.sift));
      sift_extracted += keyframe.sift_extracted;
    }
    if (keyframe.sighting) impl_->sighting_views.push_back(std::move(*keyframe.sighting));
  }
  // Views rendered where the walk did not stand: matched like keyframes, never part of the
  // occlusion cloud or the sightings (their depth is the keyframes', already in both). They
  // store ORB features only: RootSIFT matching has a slot without points for each.
  if (options.use_synthetic_views) {
    for (const store::SyntheticViewRecord& view : model.SyntheticViews()) {
      if (!IsOrbDescriptors(view.features.descriptors)) continue;
      if (std::optional<RetrievalEntry> entry =
              MakeRetrievalEntry(view.features, impl_->vocabulary, options)) {
        IndexEntry(std::move(*entry), impl_->keyframes.size(), options, &impl_->index,
                   &impl_->votes);
      }
      LocatorKeyframe keyframe = MakeLocatorKeyframe(view.source, view.world_from_cam,
                                                     view.features, impl_->vocabulary, options);
      keyframe.synthetic_view = view.id;
      if (with_sift) {
        LocatorKeyframe without_points = MakeLocatorKeyframe(
            view.source, view.world_from_cam, Features(), impl_->vocabulary, options);
        without_points.synthetic_view = view.id;
        impl_->sift_keyframes.push_back(std::move(without_points));
      }
      impl_->keyframes.push_back(std::move(keyframe));
      ++impl_->num_synthetic_views;
    }
  }
  SIGHTMAP_CHECK(any_orb_features, "the model " << model.path()
                                                << " has no keyframe with ORB features; "
                                                   "map it again with ORB features");
  FindNeighbours(options, &impl_->keyframes);
  if (with_sift) FindNeighbours(options, &impl_->sift_keyframes);
  if (with_sift && options.second_look_retrieval == LocatorOptions::SecondLookRetrieval::kVlad) {
    impl_->vlad = IndexRootSift(impl_->sift_keyframes, options.vlad.codebook);
  }
  impl_->num_sift_extracted = static_cast<size_t>(sift_extracted);
  impl_->cloud = cloud.Build(impl_->sighting_views);
  ReloadLabels(model);
}

Locator::~Locator() = default;

void Locator::ReloadLabels(const store::Model& model) {
  auto labels = std::make_shared<Impl::LabelSet>();
  labels->labels = model.Labels();
  labels->sightings = SightLabels(labels->labels, impl_->sighting_views,
                                  ToVisibilityOptions(impl_->options), &impl_->cloud);
  std::lock_guard<std::mutex> lock(impl_->labels_mutex);
  impl_->labels = std::move(labels);
}

size_t Locator::NumKeyframes() const {
  return impl_->keyframes.size() - impl_->num_synthetic_views;
}
size_t Locator::NumSyntheticViews() const { return impl_->num_synthetic_views; }
size_t Locator::NumSiftExtractedAtLoad() const { return impl_->num_sift_extracted; }
std::string Locator::LoadWarning() const {
  if (impl_->num_sift_extracted == 0) return "";
  return std::to_string(impl_->num_sift_extracted) + " of " + std::to_string(NumKeyframes()) +
         " keyframes had no stored RootSIFT features and were extracted while loading; "
         "'sightmap info --upgrade MODEL' stores them (models mapped by this sightmap have them)";
}
const LocatorOptions& Locator::options() const { return impl_->options; }
size_t Locator::NumOcclusionVoxels() const { return impl_->cloud.world_points.size(); }
std::vector<store::LabelRecord> Locator::Labels() const { return impl_->CurrentLabels()->labels; }

LocateResult Locator::Locate(const cv::Mat& photo, const std::optional<Intrinsics>& intrinsics,
                             IntrinsicsSource source,
                             const std::vector<KeyframeId>& first_keyframes) const {
  const Clock::time_point start = Clock::now();
  const LocatorOptions& options = impl_->options;
  LocateResult result;
  result.intrinsics_source = intrinsics ? source : IntrinsicsSource::kEstimated;
  auto finish = [&](Refusal refusal) {
    refusal = ExplainBareView(std::move(refusal), result.photo_detail_cells, options);
    result.matched = false;
    result.reason_code = refusal.code;
    result.reason = std::move(refusal.reason);
    result.timings.total_ms = MsSince(start);
    return result;
  };
  if (photo.empty()) return finish({UnmatchedReason::kEmptyPhoto, "the photo is empty."});

  using Matcher = LocatorOptions::Matcher;
  Clock::time_point stage = Clock::now();
  PreparedPhoto prepared = PreparePhoto(photo, intrinsics, options);
  if (options.matcher == Matcher::kRootSift) prepared = RootSiftPhoto(photo, prepared, options);
  result.intrinsics = prepared.full_candidates.front();
  result.photo_features = static_cast<int>(prepared.features.size());
  result.photo_detail_cells = prepared.detail_cells;
  result.timings.features_ms = MsSince(stage);
  if (prepared.refusal) return finish(*prepared.refusal);

  stage = Clock::now();
  const std::vector<slam::PlaceCandidate> candidates = PutKeyframesFirst(
      RetrieveCandidates(prepared.retrieval_descriptors, options.retrieval,
                         options.retrieval_candidates + options.reserve_candidates,
                         impl_->vocabulary, impl_->index, impl_->votes, impl_->keyframes, options),
      first_keyframes, impl_->keyframes);
  result.timings.retrieval_ms = MsSince(stage);
  for (const slam::PlaceCandidate& candidate : candidates) {
    const LocatorKeyframe& keyframe = impl_->keyframes[static_cast<size_t>(candidate.id)];
    result.retrieved_keyframes.push_back(keyframe.synthetic_view.valid() ? KeyframeId()
                                                                         : keyframe.id);
  }
  if (candidates.empty()) {
    return finish({UnmatchedReason::kUnknownPlace,
                   "no keyframe of the model shares a visual word with the photo."});
  }
  const std::vector<LocatorKeyframe>* matched =
      options.matcher == Matcher::kRootSift ? &impl_->sift_keyframes : &impl_->keyframes;
  // When ORB's first place refuses the photo, a second look is likely (62 of 76 photos here
  // that had one): its RootSIFT is extracted on another thread while ORB tries the other places.
  // A photo ORB then places waits for that extraction to end before it is answered.
  std::future<TimedSiftPhoto> sift_ahead;
  const auto extract_sift_ahead = [&] {
    if (options.matcher != Matcher::kOrbThenRootSift || !options.extract_sift_ahead) return;
    sift_ahead = std::async(std::launch::async, ExtractRootSiftTimed, std::cref(photo),
                            RootSiftSeed(prepared), std::cref(options));
  };
  // The photo's RootSIFT, extracted once (ahead, or when first needed).
  std::optional<PreparedPhoto> sift;
  const auto sift_photo = [&]() -> const PreparedPhoto& {
    if (!sift) {
      const Clock::time_point waiting = Clock::now();
      TimedSiftPhoto timed = sift_ahead.valid()
                                 ? sift_ahead.get()
                                 : ExtractRootSiftTimed(photo, RootSiftSeed(prepared), options);
      result.timings.features_ms += timed.ms;
      result.timings.second_look_ms += MsSince(waiting);
      sift = std::move(timed.photo);
    }
    return *sift;
  };
  // ORB's search over `ranked`; a photo ORB could not place (not one two places fit) gets a
  // second look with RootSIFT, whose answer stands when it places the photo or finds it
  // ambiguous. With the keyframes the answer's verdicts were verified against.
  struct Searched {
    Impl::Search search;
    const std::vector<LocatorKeyframe>* matched;
  };
  const auto search_from = [&](const std::vector<slam::PlaceCandidate>& ranked,
                               const std::function<void()>& first_refused) {
    Searched found{
        impl_->SearchPlaces(&prepared, ranked, static_cast<size_t>(options.retrieval_candidates),
                            *matched, options.max_places, &result.timings, first_refused),
        matched};
    if (options.matcher == Matcher::kOrbThenRootSift && !Answered(found.search.decision)) {
      if (std::optional<Impl::Search> again = impl_->SecondLook(sift_photo(), ranked, &result)) {
        found = {std::move(*again), &impl_->sift_keyframes};
      }
    }
    return found;
  };
  Searched searched = search_from(candidates, extract_sift_ahead);
  // Placed nowhere: retrieval again over a wider shortlist (wide_vote_shortlist), and the
  // search again when that ranks other keyframes first.
  if (!Answered(searched.search.decision) && options.wide_vote_shortlist > 0 &&
      options.retrieval == LocatorOptions::Retrieval::kVotes) {
    stage = Clock::now();
    LocatorOptions wide = options;
    wide.vote_shortlist = options.wide_vote_shortlist;
    const std::vector<slam::PlaceCandidate> wider =
        RetrieveCandidates(prepared.retrieval_descriptors, options.retrieval,
                           options.retrieval_candidates + options.reserve_candidates,
                           impl_->vocabulary, impl_->index, impl_->votes, impl_->keyframes, wide);
    result.timings.retrieval_ms += MsSince(stage);
    if (!SameCandidates(wider, candidates)) {
      Searched again = search_from(wider, {});
      if (Answered(again.search.decision)) {
        searched = std::move(again);
        result.answered_by_wide_retrieval = true;
      }
      result.wide_retrieval = true;
    }
  }
  matched = searched.matched;
  const Impl::Search& search = searched.search;
  const std::vector<PlaceVerdict>& verdicts = search.verdicts;
  const Decision& decision = search.decision;
  result.candidates_tried = static_cast<int>(verdicts.size());
  result.runner_up_inliers = decision.runner_up_inliers;
  if (decision.refusal) {
    if (const PlaceVerdict* would_be = WouldBeAnswer(verdicts)) {
      result.refused_world_from_cam = would_be->pose.world_from_cam;
      result.refused_inliers = would_be->inliers;
    }
    stage = Clock::now();
    result.possible_places = impl_->PossiblePlaces(verdicts, decision, *matched, photo.size());
    result.timings.visibility_ms = MsSince(stage);
    return finish(*decision.refusal);
  }
  const PlaceVerdict& best = verdicts[static_cast<size_t>(decision.winner)];
  result.matched = true;
  result.world_from_cam = best.pose.world_from_cam;
  result.inliers = best.inliers;
  result.matches = best.matches;
  result.projected_points = best.projected;
  result.inlier_cells = best.cells;
  if (best.agreement.judged) result.view_agreement = best.agreement.Score();
  result.keyframe = (*matched)[best.verified_slot].id;
  result.synthetic_view = (*matched)[best.verified_slot].synthetic_view;
  result.intrinsics = best.pose.intrinsics.Scaled(photo.cols, photo.rows);

  stage = Clock::now();
  result.appliances = impl_->AppliancesSeenFrom(result.world_from_cam, result.intrinsics);
  result.timings.visibility_ms = MsSince(stage);
  result.timings.total_ms = MsSince(start);
  return result;
}

const char* ToString(UnmatchedReason reason) {
  switch (reason) {
    case UnmatchedReason::kNone:
      return "none";
    case UnmatchedReason::kEmptyPhoto:
      return "empty_photo";
    case UnmatchedReason::kFewFeatures:
      return "few_features";
    case UnmatchedReason::kUnknownPlace:
      return "unknown_place";
    case UnmatchedReason::kAmbiguous:
      return "ambiguous";
    case UnmatchedReason::kUnseenView:
      return "unseen_view";
    case UnmatchedReason::kFewMatches:
      return "few_matches";
    case UnmatchedReason::kMatchesInOneCorner:
      return "matches_in_one_corner";
    case UnmatchedReason::kBareView:
      return "bare_view";
    case UnmatchedReason::kLooksDifferent:
      return "looks_different";
  }
  return "unknown";
}

const char* Advice(UnmatchedReason reason) {
  switch (reason) {
    case UnmatchedReason::kNone:
      return "";
    case UnmatchedReason::kEmptyPhoto:
      return "The photo is empty: take it again.";
    case UnmatchedReason::kFewFeatures:
      return "The photo shows too little detail (blank, blurred or dark): hold the phone still, "
             "turn on the light or include more of the room.";
    case UnmatchedReason::kUnknownPlace:
      return "Nothing in the photo looks like the mapped rooms: is this a mapped floor? Step back "
             "and include more of the room.";
    case UnmatchedReason::kAmbiguous:
      return "Two places look alike in this photo: include something that tells them apart, such "
             "as a door, a window or a poster.";
    case UnmatchedReason::kUnseenView:
      return "This view of the room was not seen while mapping: take the photo from where people "
             "usually stand, or have this part of the room mapped.";
    case UnmatchedReason::kFewMatches:
      return "Too few details matched: step back or include more of the room.";
    case UnmatchedReason::kMatchesInOneCorner:
      return "Only a small part of the photo matched: step back so that more of the room is in "
             "the picture.";
    case UnmatchedReason::kBareView:
      return "Too little detail: include a wall or furniture in the photo.";
    case UnmatchedReason::kLooksDifferent:
      return "What matched repeats elsewhere in the building (a poster, tiles, furniture): include "
             "more of the room, such as a door, a window or a corner.";
  }
  return "";
}

namespace {

// {"world_from_cam": {"position", "quaternion_xyzw"}}.
nlohmann::json PoseJson(const Eigen::Isometry3d& world_from_cam) {
  const Eigen::Vector3d t = world_from_cam.translation();
  const Eigen::Quaterniond q(world_from_cam.linear());
  return {
      {"world_from_cam",
       {{"position", {t.x(), t.y(), t.z()}}, {"quaternion_xyzw", {q.x(), q.y(), q.z(), q.w()}}}}};
}

nlohmann::json AppliancesJson(const std::vector<ApplianceInView>& appliances) {
  nlohmann::json out = nlohmann::json::array();
  for (const ApplianceInView& appliance : appliances) {
    out.push_back({{"name", appliance.name},
                   {"type", appliance.type},
                   {"pixel", {appliance.pixel.x(), appliance.pixel.y()}},
                   {"distance_m", appliance.distance_m},
                   {"visible", !appliance.occluded},
                   {"visible_share", appliance.visible_share}});
  }
  return out;
}

}  // namespace

nlohmann::json ToJson(const LocateResult& result) {
  nlohmann::json out;
  out["matched"] = result.matched;
  if (!result.matched) {
    out["reason"] = result.reason;
    out["reason_code"] = ToString(result.reason_code);
    out["advice"] = Advice(result.reason_code);
  }
  if (result.matched) {
    out["pose"] = PoseJson(result.world_from_cam);
    out["keyframe"] = result.keyframe.value();
    if (result.synthetic_view.valid()) out["synthetic_view"] = result.synthetic_view.value();
  } else {
    out["pose"] = nullptr;
    out["keyframe"] = nullptr;
  }
  out["inliers"] = result.inliers;
  out["matches"] = result.matches;
  out["intrinsics"] = {{"fx", result.intrinsics.fx},
                       {"fy", result.intrinsics.fy},
                       {"cx", result.intrinsics.cx},
                       {"cy", result.intrinsics.cy},
                       {"width", result.intrinsics.width},
                       {"height", result.intrinsics.height},
                       {"source", ToString(result.intrinsics_source)}};
  out["appliances"] = AppliancesJson(result.appliances);
  nlohmann::json possible = nlohmann::json::array();
  for (const PossiblePlace& place : result.possible_places) {
    possible.push_back({{"pose", PoseJson(place.world_from_cam)},
                        {"inliers", place.inliers},
                        {"keyframe", place.keyframe.value()},
                        {"appliances", AppliancesJson(place.appliances)}});
  }
  out["possible_places"] = possible;
  out["candidates_tried"] = result.candidates_tried;
  out["photo_features"] = result.photo_features;
  out["photo_detail_cells"] = result.photo_detail_cells;
  out["timings_ms"] = {
      {"features", result.timings.features_ms},      {"retrieval", result.timings.retrieval_ms},
      {"matching", result.timings.matching_ms},      {"pnp", result.timings.pnp_ms},
      {"visibility", result.timings.visibility_ms},  {"total", result.timings.total_ms},
      {"second_look", result.timings.second_look_ms}};
  out["second_look"] = result.second_look;
  out["answered_by_second_look"] = result.answered_by_second_look;
  out["wide_retrieval"] = result.wide_retrieval;
  out["answered_by_wide_retrieval"] = result.answered_by_wide_retrieval;
  return out;
}

LocateResult Locator::Locate(const Photo& photo, const IntrinsicsHint& hint,
                             const std::vector<KeyframeId>& first_keyframes) const {
  const ChosenIntrinsics chosen = ChooseIntrinsics(photo, hint);
  LocateResult result = Locate(photo.upright, chosen.intrinsics, chosen.source, first_keyframes);
  for (ApplianceInView& appliance : result.appliances) {
    appliance.pixel = photo.DisplayPixel(appliance.pixel);
  }
  for (PossiblePlace& place : result.possible_places) {
    for (ApplianceInView& appliance : place.appliances) {
      appliance.pixel = photo.DisplayPixel(appliance.pixel);
    }
  }
  return result;
}

namespace {
const std::pair<LocatorOptions::Matcher, const char*> kMatcherNames[] = {
    {LocatorOptions::Matcher::kOrb, "orb"},
    {LocatorOptions::Matcher::kRootSift, "rootsift"},
    {LocatorOptions::Matcher::kOrbThenRootSift, "orb_then_rootsift"}};
const std::pair<LocatorOptions::SecondLookRetrieval, const char*> kSecondLookRetrievalNames[] = {
    {LocatorOptions::SecondLookRetrieval::kOrb, "orb"},
    {LocatorOptions::SecondLookRetrieval::kVlad, "vlad"}};
const std::pair<LocatorOptions::Retrieval, const char*> kRetrievalNames[] = {
    {LocatorOptions::Retrieval::kVotes, "votes"},
    {LocatorOptions::Retrieval::kBagOfWords, "bag_of_words"}};
}  // namespace

void to_json(nlohmann::json& json, const LocatorOptions::Retrieval& retrieval) {
  options_json::WriteEnum(json, retrieval, kRetrievalNames);
}
void from_json(const nlohmann::json& json, LocatorOptions::Retrieval& retrieval) {
  options_json::ReadEnum(json, retrieval, kRetrievalNames);
}

void to_json(nlohmann::json& json, const LocatorOptions::Matcher& matcher) {
  options_json::WriteEnum(json, matcher, kMatcherNames);
}
void from_json(const nlohmann::json& json, LocatorOptions::Matcher& matcher) {
  options_json::ReadEnum(json, matcher, kMatcherNames);
}

void to_json(nlohmann::json& json, const LocatorOptions::SecondLookRetrieval& retrieval) {
  options_json::WriteEnum(json, retrieval, kSecondLookRetrievalNames);
}
void from_json(const nlohmann::json& json, LocatorOptions::SecondLookRetrieval& retrieval) {
  options_json::ReadEnum(json, retrieval, kSecondLookRetrievalNames);
}

SIGHTMAP_OPTIONS_JSON(LocatorOptions::Vlad, candidates, codebook)
SIGHTMAP_OPTIONS_JSON(LocatorOptions::ViewSecondOpinion, keyframes, radius_m, max_angle_deg)

SIGHTMAP_OPTIONS_JSON(LocatorOptions::Copies, offsets, look_alikes, around_m, around_keyframes,
                      max_voters, cluster_m, min_support, place_radius_m, search_radius_px,
                      min_agreement_lead)

SIGHTMAP_OPTIONS_JSON(LocatorOptions::Slide, min_sd_m, max_sd_m, reach_sd, reach_m, steps, rounds,
                      min_gain)

SIGHTMAP_OPTIONS_JSON_LONG(
    LocatorOptions,
    (features, matcher, sift_features, sift_image_side_px, sift_photo_features, sift_max_distance,
     sift_guided_max_distance, second_look_max_places, second_look_retrieval, vlad, place_threads,
     extract_sift_ahead, max_image_side_px, retrieval_candidates, reserve_candidates, retrieval,
     wide_vote_shortlist, vote_shortlist, vote_max_hamming, place_radius_m, place_max_angle_deg,
     max_places, neighbour_radius_m, neighbour_max_angle_deg, max_neighbours, match_node_level,
     match_ratio, same_point_m, max_descriptor_distance, pnp_reprojection_px, pnp_iterations,
     min_inliers, min_ransac_inliers, guided_radius_px),
    (guided_max_distance, guided_rounds, min_inlier_cells, min_inlier_cells_few_detail,
     bare_view_max_detail_cells, min_inlier_share, ceiling_only_max_thickness_m, same_pose_m,
     same_pose_deg, min_inlier_ratio_over_runner_up, ambiguity_min_agreement_lead,
     ambiguity_min_doubted_agreement, min_unique_inlier_share, twin_places, twin_min_matches,
     twin_max_shared_share, copies, slide, confident_inliers, max_rotation_from_keyframe_deg,
     min_view_agreement, min_inliers_unchecked, second_look_min_inliers_unchecked,
     view_second_opinion, view_agreement, focal_candidates_35mm, refine_estimated_focal,
     occlusion_voxel_m, occlusion_downscale, occlusion_pixel_step, occlusion_max_depth_m,
     occlusion_margin_m, occlusion_margin_ratio, occlusion_max_hole_px,
     occlusion_behind_needs_surface, occlusion_own_surface_m, min_in_view_share,
     min_unoccluded_share, use_synthetic_views))

}  // namespace sightmap::identify
