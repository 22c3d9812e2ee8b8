// Locating a phone photo (colour only, no depth) against the building model, and saying which
// labelled appliances it shows: the matching phase of ARCHITECTURE.md. A Locator loads what it
// needs from the model once (features, poses, vocabulary, labels, a coarse cloud for occlusion),
// then answers any number of photos, from several threads at once, as `sightmap serve` does.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "identify/photo.h"
#include "identify/view_agreement.h"
#include "slam/features.h"
#include "slam/vlad_index.h"
#include "store/model.h"

namespace sightmap::identify {

struct LocatorOptions {
  // Photo features: more than a keyframe's, because a phone photo sees more of the room (the
  // measured choice of 3000 is in locate_benchmark.cc).
  slam::FeatureOptions features = [] {
    slam::FeatureOptions f;
    f.max_features = 3000;
    return f;
  }();
  // What photos are matched with: the ORB features above; RootSIFT (sift_photo_features), which
  // holds up better across the viewpoint and scale changes between a person's photo and the walk's
  // keyframes; or ORB first and RootSIFT for a photo ORB could not place. ORB ranks the
  // keyframes (the vocabulary is ORB's), but for the second look's optional VLAD candidates.
  // Keyframes' RootSIFT features are those the model stores, else extracted from their stored
  // images when the model is loaded. ORB then RootSIFT by default: on 200 session-2 photos it
  // placed 8 more against the survey model (115 -> 123, wrong 4 -> 4) and the hand-held one (90 ->
  // 98, wrong 0 -> 0) than ORB alone; RootSIFT alone placed as many as ORB (115, 2 wrong) at twice
  // the median time.
  enum class Matcher { kOrb, kRootSift, kOrbThenRootSift };
  Matcher matcher = Matcher::kOrbThenRootSift;
  // The keyframes' RootSIFT, for a model that does not store it (as `map` stores it).
  slam::FeatureOptions sift_features = slam::RootSiftForPhotos();
  // The photo's RootSIFT: down to a lower contrast than the keyframes'. A person's photo is taken
  // in other light and downscaled from a larger image, and a lower threshold finds keypoints on
  // the pale walls and ceilings round a thermostat or a light that the keyframes do hold. On 200
  // session-2 photos, 0.04 -> 0.02 placed 3 more against the survey walk's SLAM model (136 -> 139
  // right, wrong 6 -> 6) and 2 more against the hand-held walk's (110 -> 112, wrong 4 -> 3);
  // 0.01-0.03 placed as many. It also finds more keypoints on textured photos, and matching them
  // took the second look's median 192-202 -> 255-285 ms at 1,000 features; 700 placed the same
  // photos at 241 ms (500: one right answer fewer, one wrong more). The keyframes' RootSIFT at
  // 0.02 too placed 3 more again on each model but gave the hand-held one 3 more wrong poses.
  slam::FeatureOptions sift_photo_features = [] {
    slam::FeatureOptions f = slam::RootSiftForPhotos();
    f.sift_contrast_threshold = 0.02;
    f.max_features = 700;
    return f;
  }();
  // RootSIFT on photos and keyframes alike at this longer side: a keyframe's 640x480 [px].
  int sift_image_side_px = 640;
  // RootSIFT matches farther than this (unit-norm descriptors: 0 same, 1.41 opposite) are dropped
  // whatever their ratio; guided matching takes a keypoint within sift_guided_max_distance.
  double sift_max_distance = 0.7;
  double sift_guided_max_distance = 0.6;
  // RootSIFT's second look (orb_then_rootsift) verifies at most this many places.
  int second_look_max_places = 6;
  // Which keyframes the second look tries: those ORB ranked (`orb`), or first the vlad.candidates
  // whose RootSIFT looks most like the photo's by VLAD (slam/vlad_index.h, its codebook trained on
  // the model's keyframes when the model is loaded: `vlad`), then ORB's. A photo ORB could not
  // place mostly shows its view from farther, nearer or another angle than the walk did, where
  // ORB's words fail and RootSIFT holds. ORB's by default: on 200 session-2 photos, with the view
  // check at 0.55, VLAD's placed 143 -> 150 against the survey walk's SLAM model with no more
  // wrong poses (3), but 116 -> 124 with wrong 2 -> 3 and 115 -> 120 with wrong 2 -> 4 against
  // the hand-held walks' (seeds 11 and 23: a window onto the simulator's repeating facade, a
  // ceiling light 1.7 m off, one of the twin desks): 3 of the 20 answers it adds are wrong,
  // against 1 in 50 of the others. Loading +1 s for the codebook, 32 KB a keyframe, locate median
  // / p95 +6% / +10% (README "Retrieval for the second look").
  enum class SecondLookRetrieval { kOrb, kVlad };
  SecondLookRetrieval second_look_retrieval = SecondLookRetrieval::kOrb;
  struct Vlad {
    int candidates = 10;         // tried before ORB's [keyframes]
    slam::VladOptions codebook;  // centres 64: vectors of 32 KB a keyframe
  };
  Vlad vlad;
  // After the first place (most photos are certain after it), places are matched and verified
  // this many at once, on OpenCV's threads; 0: as many as OpenCV has (the cores). The answer
  // does not depend on it: verdicts count in order up to the first certain one.
  int place_threads = 0;
  // With orb_then_rootsift: when ORB's first place refuses the photo, its RootSIFT is extracted on
  // another thread while ORB tries the other places (a second look is then likely). Lower
  // latency on a machine with a core to spare; off, nothing is extracted before it is needed.
  bool extract_sift_ahead = true;
  // Photos whose longer side exceeds this are downscaled for features (a 2560x1920 photo's
  // details are finer than any keyframe's; a 640x480 keyframe's camera sees a 1280x960 photo's
  // detail at about half its size) [px]; the answer's pixels are in the original image.
  int max_image_side_px = 960;
  // Retrieval: keyframes taken from the inverted index, best bag-of-words score first, each
  // verified by PnP; the best verified pose wins. The first retrieval_candidates group into places
  // (GroupPlaces); the next reserve_candidates only make places of their own after those, up to
  // max_places: the office repeats its desks and rooms, and the right place is often ranked below
  // look-alikes. On 200 session-2 photos against three SLAM models (survey, hand-held seeds 11 and
  // 23), 20 candidates and 6 places gave 142 / 116 / 114 matched with 1 / 1 / 2 wrong; 12 places
  // 143 / 118 / 115 with 1 / 0 / 2; and 40 in reserve 144 / 119 / 114 with 1 / 0 / 1 (the locate
  // median +7-9 ms, p95 160 -> 215-230 ms on a Zen 5). 60 candidates grouped alike answered 6 more
  // there but lost 2 of 128 against a 600-keyframe ground-truth model (locate_benchmark
  // --photos 200), whose first places grew with keyframes farther from what the photos show.
  int retrieval_candidates = 20;
  int reserve_candidates = 40;
  // How the keyframes are ranked: by bag-of-words scores (slam::PlaceIndex, the SLAM loop
  // detector's), or the bag of words' best vote_shortlist re-ranked by votes: the photo
  // descriptors that find a descriptor of their visual word within vote_max_hamming bits in the
  // keyframe (slam::VoteIndex). Votes by default: on 200 session-2 photos, right answers 119 ->
  // 129 against the survey walk's SLAM model (wrong 5 -> 6), 99 -> 105 against the hand-held
  // walk's (wrong 2 -> 4, with min_view_agreement 0.40); the retrieval stage's median 6 -> 9 ms.
  // A shortlist, not every keyframe: its cost does not grow with the model (README "Retrieval by
  // votes") [keyframes], [bits of 256].
  enum class Retrieval { kVotes, kBagOfWords };
  Retrieval retrieval = Retrieval::kVotes;
  int vote_shortlist = 100;
  int vote_max_hamming = 30;
  // A photo ORB and RootSIFT place nowhere (and not ambiguous) is searched again from a vote
  // ranking of the bag of words' best wide_vote_shortlist, when that ranks other keyframes; its
  // answer stands when it places the photo or finds it ambiguous. 0 = off, else more than
  // vote_shortlist [keyframes]. Off by default: every keyframe voted (100000) placed 8-13 more of
  // 200 photos on three model / photo sets but made 0-2 more wrong poses, and a quarter of the
  // photos then take a second search: locate p95 +170-220 ms, over 400 (README "A second search
  // from votes over every keyframe").
  int wide_vote_shortlist = 0;
  // Candidates within place_radius_m of an earlier candidate, looking within place_max_angle_deg
  // of it, join its place; each place (its candidates and their neighbours) is matched once
  // against the photo, at most max_places places per photo [m], [deg].
  double place_radius_m = 2.0;
  double place_max_angle_deg = 60.0;
  int max_places = 12;
  // Keyframes whose position lies within this distance of a candidate's and whose viewing direction
  // differs by less than neighbour_max_angle_deg join its 2D-3D matching [m], [deg].
  double neighbour_radius_m = 1.0;
  double neighbour_max_angle_deg = 45.0;
  int max_neighbours = 4;
  // When positive, a photo descriptor is compared only with the model descriptors under the same
  // node of the vocabulary tree this many levels below the root (ORB-SLAM's search by BoW); 0
  // compares it with every descriptor of the place. A node level cuts matching time, but its
  // ratio test no longer sees the second-nearest descriptors of other nodes, which lets wrong
  // poses through; exhaustive matching is the default (figures in locate_benchmark.cc).
  int match_node_level = 0;
  // Nearest-neighbour distance ratio for photo-to-model descriptor matches.
  double match_ratio = 0.8;
  // Neighbouring keyframes see the same 3D point with near-identical descriptors: a second-nearest
  // model descriptor whose point lies within this distance of the nearest's is the same point, and
  // does not count against the ratio test [m].
  double same_point_m = 0.05;
  // ORB matches farther than this Hamming distance are dropped whatever their ratio [bits of 256]
  // (RootSIFT's: sift_max_distance).
  int max_descriptor_distance = 80;
  // PnP RANSAC (slam::SolvePnpRansac, OpenCV's sampling): reprojection threshold [px, at the
  // feature image's scale], iterations, and the inliers a pose needs to count as matched.
  double pnp_reprojection_px = 4.0;
  // 500 iterations: a candidate with a 20% inlier share finds its pose with 0.99 confidence in
  // ~290; a wrong candidate runs them all, so more only slows down failures.
  int pnp_iterations = 500;
  int min_inliers = 25;
  // A RANSAC pose needs this many inliers before guided matching tries to grow it: the place's
  // 3D points projected with it take the nearest-descriptor photo keypoint within
  // guided_radius_px (if within guided_max_distance bits), and the pose is refined on them,
  // guided_rounds times [px at the feature image's scale], [bits of 256].
  int min_ransac_inliers = 8;
  double guided_radius_px = 8.0;
  int guided_max_distance = 64;
  int guided_rounds = 2;
  // A pose's inliers must cover this many cells of a 4x4 grid over the photo. With the twin check
  // below and confident_inliers 150, 3 cells matched more photos than 4 with no more wrong poses
  // on four SLAM models of the office (200 session-2 photos each): survey 111 -> 115 matched,
  // wrong 5 -> 4; hand-held seed 11 87 -> 90, 1 -> 0; seed 23 87 -> 93, 3 -> 3; seed 11 before
  // the poster change 98 -> 100, 5 -> 5. (Without the twin check, 3 cells let more wrong poses
  // through: 80 matched, 8 wrong against 74 and 6 with 4 cells, before the tiled ceilings.)
  int min_inlier_cells = 3;
  // A photo that shows little (its features fill few cells: a switch on a bare wall, a light on
  // the ceiling) has little to spread inliers over: it needs half its detail cells, but at least
  // this many (RequiredInlierCells in locate_stages.h).
  int min_inlier_cells_few_detail = 2;
  // A photo not matched whose features fill at most this many cells of that grid (20 features
  // each) shows too little of the room: a bare ceiling round a light, a switch on a bare wall. It
  // is answered as such, so the person includes a wall or furniture. On 200 session-2 photos
  // against the hand-held walk's SLAM model (seed 11, 10 Hz): 42 of 120 unmatched photos fill at
  // most 3 cells (25 of the 45 unmatched ceiling-light photos), 3 of 80 matched ones do.
  int bare_view_max_detail_cells = 3;
  // After guided matching, the inliers must be at least this share of the place's 3D points the
  // pose projects into the photo: right poses hold a larger share than wrong ones
  // (locate_benchmark.cc). 0.01 since the view check stands behind it: on 200 session-2 photos with
  // retrieval by votes, 0.02 -> 0.01 gave right answers 129 -> 136 (survey SLAM model) and 105 ->
  // 110 (hand-held), wrong 6 -> 6 and 4 -> 5; the poses it let through held 1.1-1.9% and the view
  // check scored them 0.62-0.94 (the wrong one: a desk photo 1.0 m off, 34 inliers). The check
  // is still needed: without it switches on bare walls were matched 10 m away, holding 0.3-1%,
  // and the view check let them through (README "A pose must look like the photo").
  double min_inlier_share = 0.01;
  // A pose whose inliers lie on one horizontal plane above the camera, 80% of them within this
  // thickness, rests on the ceiling alone: its tile grid, diffusers and lights repeat every few
  // metres and in every room, so such a pose is one guess among the repeats (the view check
  // cannot tell them apart either). It is refused as a bare view, and is nobody's rival. On 200
  // session-2 photos against the survey walk's SLAM model, the one answer like that held its 33
  // inliers within 1.7 cm, 0.95 m above the camera, and was 4.2 m off (a ceiling photo placed
  // looking the other way); the next thinnest answer spread 11 cm, on a desk below the camera.
  // Against the hand-held walks' models (seeds 11, 23) it changed no answer. 0 turns it off [m].
  double ceiling_only_max_thickness_m = 0.05;
  // Poses of two places agree when within same_pose_m and same_pose_deg; when they disagree the
  // winner needs min_inlier_ratio_over_runner_up x the runner-up's inliers (a pose refused by a
  // check above counts too, when it has min_inliers and the view check does not find it unlike
  // the photo), else the photo is ambiguous (the office's similar rooms) and not matched. With the
  // view check measured on refused poses too, on 200 session-2 photos the three SLAM models
  // (survey, hand-held seeds 11 and 23) answered 144 / 119 / 114 -> 148 / 125 / 120 photos,
  // wrong 1 / 0 / 1 -> 1 / 1 / 2: the two new wrong ones are one photo of the desk with the cream
  // box, 2.2 m off on both hand-held models, whose ambiguity had come from a look-alike 22 m away
  // scoring -0.12 and -0.05 [m], [deg], [].
  double same_pose_m = 0.5;
  double same_pose_deg = 15.0;
  double min_inlier_ratio_over_runner_up = 1.5;
  // Unless the view check scores one of the two at least this much above the other (it is then
  // the answer: the count says which place the walk saw better, the view which one the photo
  // shows); 0 turns this off. On the same photos and models 0.05 answered 2 more (survey 164, a
  // ceiling light whose runner-up one tile away scored 0.89 against 0.77, and hand-held 111, both
  // right), no wrong one.
  double ambiguity_min_agreement_lead = 0.05;
  // A pose elsewhere that the view check refused but scored at least this, with
  // min_inlier_ratio_over_runner_up x the answer's inliers, makes the photo ambiguous: a box with
  // one picture on every face, or a ceiling grid, lets a weaker pose line up the photo's texture
  // better than the right one lines up the whole view. 0 turns this off. Chosen on 600 session-2
  // photos (seeds 7, 8, 9) against the survey walk's model: three wrong answers had such a rival,
  // each the right pose (0.45, 0.52, 0.54 at 2.2-3.5x the inliers), no right answer one above
  // 0.19. Checked on the same photos against the hand-held walk's model (seed 11): two wrong
  // answers and one right one became ambiguous [].
  double ambiguity_min_doubted_agreement = 0.40;
  // And at least this share of the winner's inliers must lie in cells of an 8x8 grid over the
  // photo where the runner-up has none, when the runner-up's inliers are other things (their
  // centroids more than same_pose_m apart): a copy of the same furniture elsewhere explains the
  // same part of the photo, whatever its count. On the hand-held and survey models' 200 photos, the
  // one right answer with most of its inliers where a runner-up also has them kept 17%, every other
  // at least 31%; a photo of the wrong one of two identical desks kept 4% [0, 1].
  double min_unique_inlier_share = 0.1;
  // After the search, up to this many places that look like what the winner matched but lie
  // elsewhere (its twins: the office's identical desks, the same box in two rooms) are verified
  // against the photo too, with the winner's intrinsics; 0 turns the check off.
  int twin_places = 3;
  // A look-alike keyframe is a twin only with this many descriptor matches with the winner's
  // keyframe, and it sees the winner's own place, not a twin, when those matches join the same 3D
  // points (within same_pose_m) at twin_max_shared_share or more. Fewer matches than min_inliers:
  // the copy the photo shows may have been walked past 30-40 degrees from where the winner's
  // keyframe saw the other one (the survey's desks: 16-32 matches), and ORB matches little across
  // that turn. On the survey model's 200 photos, 15 matches and 3 places turned one twin desk's
  // wrong pose into "ambiguous" and one ambiguous photo into a right pose (25 and 2: 6 wrong).
  int twin_min_matches = 15;
  double twin_max_shared_share = 0.5;
  // Copies moved along the building (the same desk twice in a row, 2.2 m apart; CopyOffsets in
  // locate_stages.h): the winner's inliers' descriptors are matched to `look_alikes` look-alike
  // keyframes (not the winner's own) and `around_keyframes` spread within around_m of its
  // inliers, and matches to points more than same_pose_m away vote for the offset between the
  // two; offsets within cluster_m of each other voted by at least min_support inliers are a copy.
  // The winner's pose moved by each of the `offsets` best offsets is verified against the
  // keyframes that see the copy (within place_radius_m of the moved pose), its photo keypoints
  // searched within search_radius_px of the moved points (the offset is known to a few
  // centimetres: tens of pixels at a desk's distance), and decided with the rest; 0 `offsets`
  // turns the check off. On the survey model's photo 82 (the wrong one of two desks 2.2 m apart)
  // 5 cm found the offset to 1 cm from 20 inliers where 15 cm merged it with another, 10 cm off.
  // Without keyframes around the winner a hand-held photo of the other desk found no offset to it
  // (the walk passed that desk from sides unlike the winner's view). Over three SLAM models' 200
  // photos each: wrong answers 8 -> 5, the same 373 answers, locate median +14-20 ms, p95 the
  // same (README "Copies moved along the building").
  struct Copies {
    int offsets = 3;
    int look_alikes = 20;            // [keyframes]
    double around_m = 5.0;           // KeyframesAround [m]
    int around_keyframes = 10;       // [keyframes]
    int max_voters = 600;            // of the winner's inliers, evenly spread [inliers]
    double cluster_m = 0.05;         // [m]
    int min_support = 8;             // [inliers]
    double place_radius_m = 3.0;     // [m]
    double search_radius_px = 40.0;  // [px at the feature image's scale]
    // Between the winner and a copy that both pass every check, the one whose view check scores
    // this much above the other's wins; else the photo is ambiguous (DecideAmongCopies). Measured
    // pairs: right winners led their copies by 0.09-0.41, the two wrong ones trailed by 0.01
    // (ambiguous now) and 0.27 (its copy, the right desk, answers).
    double min_agreement_lead = 0.05;
  };
  Copies copies;
  // A winner whose inliers lie far away in a corner of the photo (a print on a far wall) is fixed
  // only up to a slide sideways with a turn that keeps them in place, 1.65 m and 15 deg at 6 m
  // on survey photo 157 of seed 9 (SlideAlongWeakAxis). When its position spreads more than
  // min_sd_m (PoseCovariance; and less than max_sd_m, beyond which nothing in view fixes it),
  // guided matching tries `steps` poses on each side of it along the spread's major axis, up to
  // reach_sd of its standard deviation and reach_m, and keeps the one that gains min_gain
  // inliers and a tenth, `rounds` times. The slid pose is verified again with every check and
  // answers when accepted with min_gain more inliers. 0 min_sd_m turns it off. On 1,800 answers
  // (three SLAM models, photo seeds 7 / 8 / 9) it set four wrong poses right (31 -> 27), moved a
  // right one from 0.43 to 0.14 m and changed no other answer (README "Poses that slide").
  struct Slide {
    double min_sd_m = 0.15;  // [m]
    double max_sd_m = 1.0;   // [m]
    double reach_sd = 5.0;   // [standard deviations]
    double reach_m = 2.5;    // [m]
    int steps = 20;          // on each side
    int rounds = 3;
    int min_gain = 10;  // [inliers], and a tenth more
  };
  Slide slide;
  // A verified candidate with this many inliers ends the search (the remaining candidates would
  // cost their matching time for a pose that is already certain). 150 rather than 80: a copy
  // elsewhere (the same box on another desk) gives 80-180 inliers, and the places after it may
  // hold the right one (measured with min_inlier_cells above; median locate time +5-10 ms).
  int confident_inliers = 150;
  // The paper's sanity check: the photo's viewing direction within this angle of the retrieved
  // keyframe's [deg].
  double max_rotation_from_keyframe_deg = 90.0;
  // The last check of a pose: seen from it, the model must look like the photo. The verified
  // keyframe's pixels, placed by its depth, are projected into the photo and their grey levels
  // correlated with the photo's (view_agreement.h); a pose whose ViewAgreement::Score is below
  // min_view_agreement is refused, and does not count as a runner-up: it fitted a texture that
  // repeats elsewhere (the same poster in two rooms, a ceiling's tile grid). 0 turns it off. On
  // 200 session-2 photos, of the poses all other checks accepted, the right ones (within 0.5 m and
  // 10 deg) scored at least 0.45 against the survey walk's SLAM model and 0.41 against the
  // hand-held walk's, while 7 of 10 and 4 of 6 wrong ones scored below 0.35 (a ceiling light one
  // tile off, photos matched 2-10 m away on a repeated texture, one of two identical desks).
  // With retrieval by votes more photos reach the check: the hand-held model's 112 answers held 7
  // wrong poses, three of them at 0.36-0.39 (RootSIFT's weak poses, 1.4 m and 19-21 deg off), its
  // right ones from 0.44; 0.40 refused those three and no right pose on either model. Later,
  // with the twin check and the second look, the survey's wrong answers that the other checks let
  // through scored 0.51-0.53 (a ceiling-light photo 0.52 m off whose refusal lets the search find
  // the right place, a floor lamp 1.0 m off) against right ones from 0.40: 0.55 gave survey 146 ->
  // 143 matched with wrong 5 -> 3, hand-held seed 11 118 -> 116 (wrong 2 -> 2), seed 23 117 -> 115
  // (wrong 3 -> 2); with VLAD's second look on the survey 0.50 kept 5 wrong, 0.60 gave the same
  // answers as 0.55.
  double min_view_agreement = 0.55;
  // A pose with fewer inliers than this must pass that check: when the check cannot judge it
  // (too little of the keyframe's pixels land in the photo) it is refused. On 200 session-2
  // photos the answers under 50 inliers were 5 of 142 (1 wrong) on the survey walk's SLAM model
  // and 5 of 115 (3 wrong) on the hand-held walk's; the one the check could not judge was wrong
  // (30 inliers, 5 m off). The strong ones it could not judge (151-284 inliers) were right. 60,
  // not 50: a later hand-held answer it could not judge held exactly 50 and was 2.3 m off; the
  // right ones held 83 and more.
  int min_inliers_unchecked = 60;
  // The same for a pose RootSIFT's second look found. That search tries more places with other
  // features, and the 60 above was measured on ORB's first look: on 200 session-2 photos the only
  // second-look pose the check could not judge, against the three SLAM models (survey, hand-held
  // seeds 11 and 23: 26 second-look answers), held 127 inliers and was 2.3 m off. The default,
  // sift_photo_features' 700, refuses every second-look pose the check cannot judge.
  int second_look_min_inliers_unchecked = 700;
  // When no place's pose was accepted, each pose the view check alone refused is judged again
  // against up to `keyframes` more of its place's keyframes standing within radius_m of it and
  // looking within max_angle_deg of it, their pixels projected together, and accepted when that
  // scores min_view_agreement (JudgeViewAgain in locate_stages.h); 0 keyframes turns it off. A
  // quarter of the photos are taken with furniture between the camera and what it shows, which
  // the verified keyframe may have seen past. On 600 session-2 photos (seeds 7, 8, 9): survey
  // walk's model 434 / 7 wrong -> 439 / 7, hand-held walk's 387 / 13 -> 390 / 13. Only then:
  // projected together for every pose, the keyframes' differing exposures and views lowered right
  // poses' scores as much as wrong ones' (survey: 428 / 6), and as a second opinion for every
  // refused pose, the poses it accepted beside an accepted one made 2 more wrong answers and 1
  // right one ambiguous over both models (README "A second opinion on the view") [keyframes],
  // [m], [deg].
  struct ViewSecondOpinion {
    int keyframes = 7;
    double radius_m = 3.0;
    double max_angle_deg = 60.0;
  };
  ViewSecondOpinion view_second_opinion;
  ViewAgreementOptions view_agreement;
  // With no intrinsics known, these 35 mm-equivalent focal lengths are tried and the one with most
  // PnP inliers is kept [mm] (phones: 24-30 mm main camera).
  std::vector<double> focal_candidates_35mm = {22.0, 26.0, 30.0, 35.0};
  // Then the kept focal length is refined together with the pose on the inliers (principal point
  // fixed at the centre, square pixels), so the answer is not limited to the candidates' grid.
  bool refine_estimated_focal = true;
  // Occlusion: the model's surfaces are kept as a voxel cloud of this cell size [m]; an appliance
  // point is occluded when that cloud, drawn from the photo's pose into a z-buffer of
  // 1/occlusion_downscale of the photo, has a surface nearer than the point by more than
  // occlusion_margin_m + occlusion_margin_ratio x its distance. 0.25 m: a label point clicked on
  // one face of an appliance lies behind its other faces seen from elsewhere (the survey's printer
  // point 0.23 m behind the printer's near side seen from 1.3 m), or on a wall beside a door frame
  // (a switch 0.21 m behind the frame's edge). On 200 session-2 photos 0.15 -> 0.25 took the
  // matched photos with recall >= 0.8 from 89.8 / 88.3 / 84.8% to 92.2 / 91.0 / 86.7% on the
  // survey and hand-held seed 11 and 23 SLAM models, and 85.2 -> 91.3% on locate_benchmark's
  // ground-truth model, the occluded instances reported visible unchanged on all four (1.0 / 1.1
  // / 1.1 / 1.0%, as with 0.30 and 0.40: those photos hold no occluder that close in front of an
  // appliance, and a lamp behind a monitor would be one; 0.25 is what the appliances' own depth
  // asks) [m], [].
  double occlusion_voxel_m = 0.05;
  int occlusion_downscale = 8;
  // Every occlusion_pixel_step-th pixel of each keyframe's depth (both directions) goes into the
  // cloud, up to occlusion_max_depth_m (farther depth is too noisy to hide anything) [px], [m].
  int occlusion_pixel_step = 4;
  double occlusion_max_depth_m = 5.0;
  double occlusion_margin_m = 0.25;
  double occlusion_margin_ratio = 0.05;
  // A keyframe's depth holes (screens and glass return no depth) enclosed by its surfaces within
  // this many of its sampled pixels are filled with the farthest of them before they go into the
  // cloud, unless another keyframe saw through them (OcclusionCloudBuilder::AddDepth, Build); and
  // a point seen from the side opposite the walk's is hidden where the z-buffer reaches past it
  // (VisibilityOptions::behind_needs_own_surface) [px].
  int occlusion_max_hole_px = 40;
  bool occlusion_behind_needs_surface = true;
  // A surface on the line of sight within this distance of the plane an appliance point sits on
  // is that plane seen at a grazing angle and hides nothing (VisibilityOptions::own_surface_m;
  // 0 = off) [m].
  double occlusion_own_surface_m = 0.15;
  // An appliance is in view when at least this share of its points project inside the image in
  // front of the camera, and visible when at least this share of those are not occluded.
  double min_in_view_share = 0.5;
  double min_unoccluded_share = 0.5;
  // Match photos against the model's synthetic views too (`sightmap synthesize`): views rendered
  // where the walk did not stand, indexed and matched like keyframes.
  bool use_synthetic_views = true;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const LocatorOptions& options);
void from_json(const nlohmann::json& json, LocatorOptions& options);

struct ApplianceInView {
  std::string name;
  std::string type;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // centre of its visible points, photo pixels
  double distance_m = 0.0;                          // camera to the nearest point [m]
  bool occluded = false;  // in the view cone but hidden behind a model surface
  // Share of the label's points inside the photo and not hidden: below 1 the appliance is partly
  // in view (cut by the photo's edge, or partly behind something).
  double visible_share = 1.0;
};

// A place an ambiguous photo may have been taken at, and what would be in view from there.
struct PossiblePlace {
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  int inliers = 0;
  KeyframeId keyframe;                      // the keyframe holding most of the pose's inliers
  std::vector<ApplianceInView> appliances;  // as LocateResult::appliances
};

// Time spent per stage [ms].
struct LocateTimings {
  double features_ms = 0.0;
  double retrieval_ms = 0.0;
  double matching_ms = 0.0;  // 2D-3D
  double pnp_ms = 0.0;
  double visibility_ms = 0.0;
  double total_ms = 0.0;
  // The wall time the RootSIFT second look added after ORB's search (0 when it did not run): its
  // matching and PnP, and what was left of its extraction (with extract_sift_ahead the extraction
  // may have run during ORB's search; features_ms counts all of it).
  double second_look_ms = 0.0;
};

// Why a photo was not matched, in classes a client can explain to the person holding the phone.
enum class UnmatchedReason {
  kNone,                // matched
  kEmptyPhoto,          // no pixels
  kFewFeatures,         // blank, blurred or dark
  kUnknownPlace,        // nothing in it looks like any keyframe
  kAmbiguous,           // two places fit about as well
  kUnseenView,          // the best pose turns too far from every keyframe that saw the place
  kFewMatches,          // too few details agree on a pose
  kMatchesInOneCorner,  // enough details agree, but in one small part of the photo
  kBareView,            // the photo's detail is in a corner of it: a bare ceiling or wall
  kLooksDifferent,      // a pose fits the details, but the model seen from it is unlike the photo
};
// "few_features", ...: stable names for JSON.
const char* ToString(UnmatchedReason reason);
// One sentence for a person, not an engineer: what went wrong and what to do about it.
const char* Advice(UnmatchedReason reason);

struct LocateResult {
  bool matched = false;
  std::string reason;  // why not, when not matched (one sentence, with the figures)
  UnmatchedReason reason_code = UnmatchedReason::kNone;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  int inliers = 0;
  int matches = 0;      // 2D-3D matches of the winning candidate
  KeyframeId keyframe;  // the retrieved keyframe holding most of the pose's inliers
  // When that was a synthetic view: its id (`keyframe` is then the keyframe it was rendered from).
  SyntheticViewId synthetic_view;
  Intrinsics intrinsics;  // at the photo's full resolution
  IntrinsicsSource intrinsics_source = IntrinsicsSource::kEstimated;
  // Appliances in the view cone, nearest first; occluded ones are listed with occluded = true
  // so a client can say "behind the wall", but they are not "in view".
  std::vector<ApplianceInView> appliances;
  LocateTimings timings;
  // Bag-of-words candidates verified by PnP, and features found on the photo.
  int candidates_tried = 0;  // places verified (groups of nearby candidates; twins, copies too)
  // Inliers of the best pose that disagrees with the answer's (0 when none).
  int runner_up_inliers = 0;
  // The winning place's 3D points (one per keyframe that has it) that the pose projects into the
  // photo, in front of the camera.
  int projected_points = 0;
  int inlier_cells = 0;  // cells of a 4x4 grid over the photo holding an inlier
  // ViewAgreement::Score of the answer's pose (nullopt when the check is off or could not judge).
  std::optional<double> view_agreement;
  int photo_features = 0;
  // Cells of a 4x4 grid over the photo holding at least 20 of its features: a
  // photo of a bare ceiling or wall has its few features in one or two cells.
  int photo_detail_cells = 0;
  // The RootSIFT search ran (matcher orb_then_rootsift, ORB placed the photo nowhere), and its
  // answer is the one given.
  bool second_look = false;
  bool answered_by_second_look = false;
  // The search ran again from the wider retrieval (LocatorOptions::wide_vote_shortlist), and its
  // answer is the one given.
  bool wide_retrieval = false;
  bool answered_by_wide_retrieval = false;
  // When not matched: the pose the answer would have been (an ambiguous photo's winner, else the
  // pose with most inliers that the checks refused) and its inliers; to tell right refusals from
  // wrong ones.
  std::optional<Eigen::Isometry3d> refused_world_from_cam;
  int refused_inliers = 0;
  // When ambiguous: the two places that fit about as well (Decision::ambiguous, the leader
  // first), each with the appliances in view from it. A person may tell which it is from them; when
  // both hold the same kind of appliance, that much is known either way.
  std::vector<PossiblePlace> possible_places;
  // The first retrieval's candidates (retrieval_candidates, then reserve_candidates), best first:
  // each a keyframe's id, or an invalid id for a synthetic view. To measure how high retrieval
  // ranks the keyframes that saw the photo's view (`eval identify`'s retrieval ranks).
  std::vector<KeyframeId> retrieved_keyframes;
};

// The answer's JSON: {"matched", "reason"?, "reason_code"?, "advice"?, "pose": {"world_from_cam":
// {"position", "quaternion_xyzw"}}, "inliers", "matches", "keyframe", "intrinsics":
// {"fx","fy","cx","cy", "width","height","source"}, "appliances":
// [{"name","type","pixel":[u,v],"distance_m", "visible","visible_share"}], "possible_places":
// [{"pose", "inliers", "keyframe", "appliances"}] (empty unless ambiguous), "timings_ms": {...}}.
nlohmann::json ToJson(const LocateResult& result);

// How far a Locator's loading has got: keyframes read so far (on every loading thread) of the
// model's total.
using LoadProgress = std::function<void(size_t loaded, size_t total)>;

class Locator {
 public:
  // Reads the model's keyframes (features, poses, depth for the occlusion cloud), its synthetic
  // views (with use_synthetic_views), vocabulary and labels. A model without a vocabulary (fewer
  // keyframes than the mapper trains one on) gets one trained from its keyframes, and a model of at
  // most retrieval_candidates keyframes verifies every one of them. With second_look_retrieval
  // vlad the keyframes' RootSIFT codebook is trained here (about 1 s for 1,342 keyframes; none for
  // a model with fewer RootSIFT rows than centres x sample_step). Throws Error with one line when
  // the model has no keyframe. `progress`, when given, is called on the constructing thread only:
  // after each keyframe it reads, every 0.2 s while it waits for the other loading thread, and
  // last with loaded == total (a building's model takes seconds).
  Locator(const store::Model& model, const LocatorOptions& options = LocatorOptions(),
          const LoadProgress& progress = {});
  ~Locator();
  Locator(const Locator&) = delete;
  Locator& operator=(const Locator&) = delete;

  // Locates one photo (BGR). `intrinsics` at the photo's resolution, or nullopt to estimate them
  // (then intrinsics_source is kEstimated). Thread-safe: concurrent calls share the loaded model.
  // `first_keyframes`, when given, are searched before whatever the first retrieval ranks (those
  // it ranked in its order, then the rest in the order given; ids the model lacks are ignored;
  // the wider second search of wide_vote_shortlist ranks on its own): a measurement of what
  // retrieval costs, with the keyframes known to have seen the photo's view (`eval identify
  // --seeing-keyframes-first`), not something a user can know.
  LocateResult Locate(const cv::Mat& photo, const std::optional<Intrinsics>& intrinsics,
                      IntrinsicsSource source = IntrinsicsSource::kGiven,
                      const std::vector<KeyframeId>& first_keyframes = {}) const;
  // Locates a decoded photo with intrinsics by ChooseIntrinsics(photo, hint); the appliances'
  // pixels are in the picture a viewer shows (Photo::DisplayPixel). Throws InvalidArgument when
  // the hint does not fit the photo.
  LocateResult Locate(const Photo& photo, const IntrinsicsHint& hint,
                      const std::vector<KeyframeId>& first_keyframes = {}) const;

  // Re-reads the labels (after `label add` on a served model).
  void ReloadLabels(const store::Model& model);

  size_t NumKeyframes() const;       // real keyframes
  size_t NumSyntheticViews() const;  // loaded synthetic views
  // Keyframes whose RootSIFT features the model did not store, extracted when it was loaded (a
  // model mapped without them: slower to load).
  size_t NumSiftExtractedAtLoad() const;
  // One line for the person who loaded the model when loading it did extra work they can avoid
  // (RootSIFT extracted at load); empty otherwise.
  std::string LoadWarning() const;
  const LocatorOptions& options() const;
  // Voxels of the occlusion cloud (0 when the model stores no depth).
  size_t NumOcclusionVoxels() const;
  // Labels currently loaded.
  std::vector<store::LabelRecord> Labels() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::identify
