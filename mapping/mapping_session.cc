#include "mapping/mapping_session.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <iomanip>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/peak_memory.h"
#include "core/statistics.h"
#include "core/timing.h"
#include "mapping/capture_stage.h"
#include "mapping/map_stage.h"
#include "mapping/model_restore.h"
#include "mapping/write_stage.h"
#include "slam/trajectory_eval.h"
#include "store/trajectory.h"

namespace sightmap::mapping {
namespace {

using Clock = std::chrono::steady_clock;

TimestampNs WallClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

const char* ToString(StopReason reason) {
  switch (reason) {
    case StopReason::kSourceEnded:
      return "the source ended";
    case StopReason::kSignal:
      return "interrupted (Ctrl-C or SIGTERM)";
    case StopReason::kUserStop:
      return "stopped from the preview window";
    case StopReason::kSourceFailed:
      return "the source failed";
    case StopReason::kMaxKeyframes:
      return "the keyframe limit was reached";
  }
  return "unknown";
}

bool MappingOptions::Check(std::string* error) const {
  if (source.empty()) {
    *error = "no source";
    return false;
  }
  if (model_path.empty()) {
    *error = "no model file";
    return false;
  }
  if (start_frame < 0 || max_keyframes < 0) {
    *error = "start_frame and max_keyframes must be >= 0";
    return false;
  }
  if (track_every < 1) {
    *error = "track_every must be >= 1";
    return false;
  }
  if (replay_nice_increment < 0 || replay_nice_increment > 19) {
    *error = "replay_nice_increment must be in [0, 19]";
    return false;
  }
  if (replay_write_nice_increment < 0 || replay_write_nice_increment > 19) {
    *error = "replay_write_nice_increment must be in [0, 19]";
    return false;
  }
  if (frame_queue_capacity < 1 || keyframe_queue_capacity < 1 || write_queue_capacity < 1) {
    *error = "queue capacities must be >= 1";
    return false;
  }
  if (photo_features &&
      !PhotoFeatureExtraction{photo_feature_options, photo_feature_side_px}.Check(error)) {
    return false;
  }
  return source_options.Check(error) && sampler.Check(error) && tracking.Check(error) &&
         mapper.Check(error) && model.Check(error) && ply.Check(error) && view.Check(error);
}

MappingSession::MappingSession(const MappingOptions& options) : options_(options) {
  SIGHTMAP_CHECK_OPTIONS(options_);
}

void MappingSession::RequestStop(StopReason reason) {
  int expected = -1;
  stop_reason_.compare_exchange_strong(expected, static_cast<int>(reason));
}

// The stages of one run and what the session's own loop needs of them.
struct MappingSession::Pipeline {
  const capture::SourceMetadata& meta;
  slam::Mapper& mapper;
  MapViewFeed* view;  // may be null
  CaptureStage& capture;
  TrackStage& track;
  BoundedQueue<KeyframeItem>& keyframes;
  MapStage& map;
  WriteStage& writer;
  Clock::time_point start;
  bool resumed = false;
};

namespace {

std::unique_ptr<MapViewFeed> OpenView(const MappingOptions& options,
                                      const capture::SourceMetadata& meta, std::ostream* notices) {
  if (!options.show_view) return nullptr;
  MapViewFeedOptions view_options = options.view;
  // A map anchored to the source's ground truth is in the scene's frame, whose up is +z (the
  // simulator's building, TUM's motion capture), not the first camera's -y: the floor plan was
  // a side view of the building.
  if (options.anchor_to_ground_truth && meta.has_ground_truth) {
    view_options.world_up = Eigen::Vector3d::UnitZ();
  }
  return MapViewFeed::Create(view_options, notices);
}

// The tracker works with the mapper's features and depth, at the keyframe rate asked for.
TrackStageOptions TrackingOptions(const MappingOptions& options) {
  TrackStageOptions tracking = options.tracking;
  tracking.track = tracking.track && !options.ground_truth_poses;
  tracking.tracker.features = options.mapper.features;
  tracking.tracker.registration = options.mapper.registration;
  tracking.tracker.depth_downscale = options.mapper.depth_downscale;
  tracking.tracker.keyframe_rate_hz = options.sampler.rate_hz;
  return tracking;
}

CaptureStageOptions CaptureOptions(const MappingOptions& options, bool live, bool track,
                                   std::optional<TimestampNs> continue_after) {
  CaptureStageOptions capture;
  capture.start_frame = options.start_frame;
  capture.after_timestamp_ns = continue_after;
  capture.live = live;
  // Without tracking only keyframes are needed: sampled at capture, a live sensor drops keyframes
  // the mapper cannot take, not frames in between.
  capture.sample_keyframes = !track;
  capture.sampler = options.sampler;
  capture.take_every = options.track_every;
  capture.replay_nice_increment = options.replay_nice_increment;
  return capture;
}

store::SessionRecord MakeSessionRecord(const MappingOptions& options,
                                       const capture::SourceMetadata& meta) {
  store::SessionRecord record;
  record.start_time_ns = WallClockNs();
  record.source = options.source;
  record.device_name = meta.device_name;
  record.device_serial = meta.serial;
  record.intrinsics = meta.intrinsics;
  // What ran: the tracker's options as TrackingOptions() made them.
  MappingOptions ran = options;
  ran.tracking = TrackingOptions(options);
  record.options_json = nlohmann::json(ran).dump();
  return record;
}

// The last frame the model stored from this very source (the same SOURCE string), for a resumed
// replay to continue after; nullopt when no session mapped it.
std::optional<TimestampNs> LastStoredTimestamp(const store::Model& model,
                                               const std::string& source) {
  std::vector<SessionId> same_source;
  for (const store::SessionRecord& session : model.Sessions()) {
    if (session.source == source) same_source.push_back(session.id);
  }
  if (same_source.empty()) return std::nullopt;
  std::optional<TimestampNs> last;
  for (const store::KeyframeInfo& keyframe : model.Keyframes()) {
    if (std::find(same_source.begin(), same_source.end(), keyframe.session) == same_source.end()) {
      continue;
    }
    if (!last || keyframe.timestamp_ns > *last) last = keyframe.timestamp_ns;
  }
  return last;
}

// A start frame past a recording's known end is said before the model is touched.
void CheckStartFrame(const MappingOptions& options, const capture::SourceMetadata& meta) {
  const std::optional<int64_t> frames = meta.depth_frame_count;
  if (frames && options.start_frame >= *frames) {
    SIGHTMAP_THROW(InvalidArgument, "the start frame " << options.start_frame
                                                       << " is past the end of " << options.source
                                                       << ", which has " << *frames
                                                       << " frames (0.." << *frames - 1 << ")");
  }
}

// A session that got no frame at all mapped nothing: that is said, not reported as a success.
void CheckFramesCame(const MappingOptions& options, const CaptureStage& capture, StopReason reason,
                     std::optional<TimestampNs> continue_after) {
  if (reason != StopReason::kSourceEnded || capture.frames_read() > capture.frames_skipped()) {
    return;
  }
  if (continue_after) {
    SIGHTMAP_THROW(Error, "nothing left to map: the model already holds "
                              << options.source << " up to its last frame (t = " << std::fixed
                              << std::setprecision(3) << 1e-9 * *continue_after
                              << " s); --start-frame 0 maps it again from the start");
  }
  SIGHTMAP_THROW(Error, "nothing to map: " << options.source << " has " << capture.frames_read()
                                           << " frames, none from frame " << options.start_frame
                                           << " on");
}

void NoteContinued(const MappingOptions& options, TimestampNs continue_after,
                   std::ostream* notices) {
  if (!notices) return;
  *notices << "continuing " << options.source << " after its last stored frame (t = " << std::fixed
           << std::setprecision(3) << 1e-9 * continue_after
           << " s); --start-frame 0 maps it from the start\n"
           << std::defaultfloat;
}

void NoteResumed(const MappingOptions& options, const RestoredModel& restored, int64_t interrupted,
                 std::ostream* notices) {
  if (!notices) return;
  *notices << "resuming " << options.model_path << ": " << restored.store_ids.size()
           << " keyframes in " << restored.segment_members.size() << " segment(s)"
           << (interrupted > 0
                   ? ", " + std::to_string(interrupted) + " crashed session(s) marked interrupted"
                   : std::string())
           << "\n";
}

// Where a resumed replay of the same source continues: after the last frame the model stored
// from it (a live sensor's clock restarts, so never for one), and from the newest keyframe's frame
// when that was the last stored one (the camera is where it left it).
struct ContinuePoint {
  std::optional<TimestampNs> after;
  std::optional<RgbdFrame> from;
};

ContinuePoint FindContinuePoint(const MappingOptions& options, const capture::SourceMetadata& meta,
                                const store::Model& model, const RestoredModel& restored,
                                bool resumed, slam::Mapper* mapper, std::ostream* notices) {
  ContinuePoint point;
  if (!resumed || !options.continue_replay || meta.kind == "openni") return point;
  point.after = LastStoredTimestamp(model, options.source);
  if (!point.after) return point;
  NoteContinued(options, *point.after, notices);
  if (*point.after == restored.last_timestamp_ns) {
    mapper->ContinueWalk();
    point.from = NewestKeyframeFrame(model, restored);
  }
  return point;
}

// The figures of the map, its tracking and its accuracy, once every stage has ended.
void Summarise(const slam::Mapper& mapper, const MapStage& map, const TrackStage& track,
               bool tracked, const CaptureStage& capture, const store::Model& model,
               MappingSummary* summary) {
  const store::ModelSummary model_summary = model.Summary();
  summary->keyframes = map.keyframes();
  summary->model_keyframes = model_summary.keyframes;
  summary->loops = mapper.NumLoopClosures();
  summary->segments = mapper.NumSegments();
  summary->largest_segment_keyframes = model_summary.largest_segment_keyframes;
  summary->largest_part_ratio = model_summary.LargestPartRatio();
  summary->prior_links = model_summary.prior_links;
  summary->axes_keyframes = mapper.NumManhattanKeyframes();
  summary->model_bytes = model_summary.size_bytes;
  const TrackStageReport& tracking = track.report();
  summary->tracked_frames = tracked ? tracking.counters.frames : 0;
  summary->dense_frames = tracking.counters.dense;
  summary->dense_at_rest_frames = tracking.counters.dense_at_rest;
  summary->blind_frames = tracking.counters.blind;
  summary->early_keyframes = tracking.counters.early_keyframes;
  summary->frames_before_start = tracking.counters.before_start;
  summary->track_median_ms = 1e3 * Percentile(tracking.frame_s, 0.5);
  summary->track_p95_ms = 1e3 * Percentile(tracking.frame_s, 0.95);
  summary->keyframe_median_ms = 1e3 * Percentile(map.keyframe_seconds(), 0.5);
  summary->keyframe_p95_ms = 1e3 * Percentile(map.keyframe_seconds(), 0.95);
  summary->dropped_frames = capture.dropped_frames();
  summary->unpaired_frames = capture.unpaired_frames();
  summary->frames_read = capture.frames_read();
  summary->frames_skipped = capture.frames_skipped();
  summary->links_rejected_after_commit = map.links_rejected_after_commit();
  summary->links_reactivated_at_end = map.links_reactivated_at_end();
  summary->final_optimisation_s = map.final_optimisation_s();
  summary->joined_stored_map = map.joined_stored_map();
  if (const std::optional<slam::TrajectoryError> error = map.Accuracy()) {
    summary->ate_rmse_m = error->ate_rmse_m;
    summary->ate_max_m = error->ate_max_m;
    summary->ate_poses = error->matched_poses;
  }
}

// The PLY and the trajectory, read from the model.
void WriteExports(const MappingOptions& options, const store::Model& model, std::ostream* notices,
                  MappingSummary* summary) {
  if (summary->model_keyframes == 0) return;
  if (!options.ply_path.empty()) {
    if (notices) {
      *notices << "writing " << options.ply_path << " from " << summary->model_keyframes
               << " keyframes\n"
               << std::flush;
    }
    summary->ply_points = store::ExportPly(model, options.ply_path, options.ply).written_points;
    summary->ply_path = options.ply_path;
  }
  if (!options.trajectory_path.empty()) {
    WriteTumTrajectory(options.trajectory_path, store::ModelTrajectory(model));
    summary->trajectory_path = options.trajectory_path;
  }
}

}  // namespace

MappingProgress MappingSession::Progress(const Pipeline& pipeline) const {
  MappingProgress progress;
  progress.keyframes = pipeline.map.keyframes();
  progress.model_keyframes = static_cast<int64_t>(pipeline.mapper.NumKeyframes());
  progress.loops = pipeline.mapper.NumLoopClosures();
  progress.dropped_frames = pipeline.capture.dropped_frames();
  progress.frames_passed = pipeline.capture.frames_passed();
  if (pipeline.meta.depth_frame_count) progress.frames_total = *pipeline.meta.depth_frame_count;
  progress.tracking = pipeline.mapper.tracking_state();
  progress.resumed = pipeline.resumed;
  progress.joined_stored_map = pipeline.map.joined_stored_map();
  progress.paused = pipeline.view && pipeline.view->paused();
  progress.elapsed_s = SecondsSince(pipeline.start);
  progress.keyframes_per_s =
      progress.elapsed_s > 0.0 ? static_cast<double>(progress.keyframes) / progress.elapsed_s : 0.0;
  return progress;
}

bool MappingSession::StopRequested(const Pipeline& pipeline) {
  if (interrupt_flag_ && interrupt_flag_->load()) RequestStop(StopReason::kSignal);
  if (pipeline.view && pipeline.view->stop_requested()) RequestStop(StopReason::kUserStop);
  return stop_reason_.load() >= 0 || pipeline.writer.failed();
}

void MappingSession::MapKeyframes(const Pipeline& pipeline) {
  Clock::time_point last_progress = Clock::now();
  while (!StopRequested(pipeline)) {
    KeyframeItem item;
    const auto popped = pipeline.keyframes.Pop(&item, std::chrono::milliseconds(100));
    if (popped == BoundedQueue<KeyframeItem>::PopResult::kEnd) return;
    if (popped == BoundedQueue<KeyframeItem>::PopResult::kTimeout) {
      if (progress_ && SecondsSince(last_progress) > 1.0) {
        progress_(Progress(pipeline));
        last_progress = Clock::now();
      }
      continue;
    }
    std::vector<WriteTask> tasks = pipeline.map.Map(std::move(item));
    const MappingProgress progress = Progress(pipeline);
    tasks.front().status = FeedStatus{progress.model_keyframes, progress.loops, progress.tracking,
                                      progress.keyframes_per_s, progress.elapsed_s};
    for (WriteTask& task : tasks) {
      if (!pipeline.writer.Push(std::move(task))) return;  // the writer failed
    }
    if (progress_) {
      progress_(progress);
      last_progress = Clock::now();
    }
    if (options_.max_keyframes > 0 && pipeline.map.keyframes() >= options_.max_keyframes) {
      RequestStop(StopReason::kMaxKeyframes);
    }
  }
}

std::exception_ptr MappingSession::DrainStages(const Pipeline& pipeline) {
  // Stop capturing (frames still queued are not mapped) and tracking, then the whole map is
  // optimised once more and every pose written, and the writer drains and ends.
  pipeline.capture.Stop();
  pipeline.capture.Join();
  pipeline.keyframes.Close();
  pipeline.keyframes.Clear();
  pipeline.track.Join();
  std::exception_ptr error = pipeline.track.error();
  if (!error && !pipeline.writer.failed() && pipeline.map.keyframes() > 0) {
    if (progress_ && !options_.ground_truth_poses) {  // true poses are not optimised
      MappingProgress optimising = Progress(pipeline);
      optimising.optimising_whole_map = true;
      progress_(optimising);
    }
    try {
      pipeline.writer.Push(pipeline.map.Finish());
    } catch (...) {
      error = std::current_exception();  // the poses written with each keyframe stand
    }
  }
  pipeline.writer.Finish();
  return error;
}

void MappingSession::EndSession(const Pipeline& pipeline, store::Model* model, SessionId session,
                                const std::exception_ptr& map_error, StopReason reason) {
  const bool failed = map_error || pipeline.writer.failed();
  const store::SessionEnd end_state = failed || reason == StopReason::kSourceFailed
                                          ? store::SessionEnd::kInterrupted
                                          : store::SessionEnd::kFinished;
  try {
    model->EndSession(session, end_state, WallClockNs());
  } catch (const Error&) {
    if (!failed) throw;  // the first failure is the one to report
  }
  if (pipeline.view) pipeline.view->Finish();
  if (map_error) std::rethrow_exception(map_error);
  if (pipeline.writer.failed()) std::rethrow_exception(pipeline.writer.error());
  if (reason == StopReason::kSourceFailed && pipeline.map.keyframes() == 0) {
    SIGHTMAP_THROW(Error, *pipeline.capture.error());
  }
}

MappingSummary MappingSession::Run(std::ostream* notices) {
  MappingSummary summary;

  // The source first: without one, the model is not touched.
  std::unique_ptr<capture::RgbdSource> source =
      capture::OpenSource(options_.source, options_.source_options);
  const capture::SourceMetadata meta = source->metadata();
  summary.source_kind = meta.kind;
  const bool live = options_.live || meta.kind == "openni";
  const Intrinsics camera = meta.intrinsics;
  // Said before the model is touched when the source has none at all; a folder whose ground truth
  // has gaps fails at the first frame without it.
  if (options_.ground_truth_poses && !meta.has_ground_truth) {
    throw NoGroundTruthError("this " + meta.kind + " source");
  }
  CheckStartFrame(options_, meta);
  std::unique_ptr<MapViewFeed> view = OpenView(options_, meta, notices);

  store::Model model = store::Model::Open(options_.model_path, options_.model);
  // Owned apart so that its memory (features, depth and the graph of every keyframe) is freed
  // before the PLY export, which reads the model: a 3,000-keyframe run would hold both at once.
  auto mapper = std::make_unique<slam::Mapper>(camera, options_.mapper);
  // Sessions a crash left running (with or without keyframes) were interrupted.
  summary.interrupted_sessions_marked = model.MarkRunningSessionsInterrupted(WallClockNs());
  // A model labelled after an earlier session: the floor plan shows from where each label was
  // seen, the restored keyframes included, so the walk can go to what is missing.
  if (view) view->SetLabels(model.Labels());
  const RestoredModel restored =
      RestoreModel(model, camera, options_.mapper.dense_refinement, mapper.get(), view.get());
  summary.resumed = !restored.store_ids.empty();
  summary.restored_keyframes = static_cast<int64_t>(restored.store_ids.size());
  if (summary.resumed) {
    NoteResumed(options_, restored, summary.interrupted_sessions_marked, notices);
  }
  ContinuePoint resume =
      FindContinuePoint(options_, meta, model, restored, summary.resumed, mapper.get(), notices);
  if (resume.after) summary.continued_after_s = 1e-9 * static_cast<double>(*resume.after);

  summary.session_number = static_cast<int64_t>(model.Sessions().size()) + 1;
  const SessionId session = model.BeginSession(MakeSessionRecord(options_, meta));
  summary.session = session.value();

  // capture -> frames -> track -> keyframes -> map (this thread) -> writer.
  const TrackStageOptions tracking = TrackingOptions(options_);
  BoundedQueue<RgbdFrame> frames(static_cast<size_t>(options_.frame_queue_capacity));
  BoundedQueue<KeyframeItem> keyframes(static_cast<size_t>(options_.keyframe_queue_capacity));
  const Clock::time_point start = Clock::now();
  std::optional<PhotoFeatureExtraction> photo_features;
  if (options_.photo_features) {
    photo_features =
        PhotoFeatureExtraction{options_.photo_feature_options, options_.photo_feature_side_px};
  }
  WriteStage writer(&model, view.get(), static_cast<int>(summary.session_number),
                    restored.store_ids, static_cast<size_t>(options_.write_queue_capacity),
                    std::move(photo_features), live ? 0 : options_.replay_write_nice_increment);
  TrackStage track(camera, tracking, &frames, &keyframes, std::move(resume.from));
  CaptureStage capture(source.get(), CaptureOptions(options_, live, tracking.track, resume.after),
                       &frames, view.get());
  MapStage map(mapper.get(), session, camera,
               {options_.anchor_to_ground_truth, options_.ground_truth_poses}, restored);
  const Pipeline pipeline{meta,      *mapper, view.get(), capture, track,
                          keyframes, map,     writer,     start,   summary.resumed};
  std::exception_ptr map_error;
  try {
    MapKeyframes(pipeline);
  } catch (...) {
    map_error = std::current_exception();
  }
  // Whatever happened, the stages are drained in order before anything is reported.

  if (!map_error) map_error = DrainStages(pipeline);
  if (stop_reason_.load() >= 0) {
    summary.reason = static_cast<StopReason>(stop_reason_.load());
  } else if (capture.error()) {
    summary.reason = StopReason::kSourceFailed;
    summary.reason_detail = *capture.error();
  }
  EndSession(pipeline, &model, session, map_error, summary.reason);
  try {
    CheckFramesCame(options_, capture, summary.reason, resume.after);
  } catch (const Error&) {
    // A run that mapped nothing leaves no empty session behind: `info` would count it.
    model.DeleteEmptySession(session);
    throw;
  }

  if (progress_) {
    MappingProgress last = Progress(pipeline);
    last.finished = true;
    progress_(last);
  }
  summary.elapsed_s = SecondsSince(start);
  summary.keyframes_per_s =
      summary.elapsed_s > 0.0 ? static_cast<double>(map.keyframes()) / summary.elapsed_s : 0.0;
  // Nothing writes to the model after this (the PLY and the trajectory only read it).
  Summarise(*mapper, map, track, tracking.track, capture, model, &summary);

  // After the view finished: its description counts the images that could not be written.
  if (view) summary.view = view->description();
  // Nothing below uses the mapper or the view.
  mapper.reset();
  view.reset();
  WriteExports(options_, model, notices, &summary);
  summary.peak_rss_mib = PeakRssMiB();
  return summary;
}

SIGHTMAP_OPTIONS_JSON(MappingOptions, source, model_path, ply_path, trajectory_path, start_frame,
                      continue_replay, max_keyframes, live, anchor_to_ground_truth,
                      ground_truth_poses, frame_queue_capacity, keyframe_queue_capacity,
                      write_queue_capacity, source_options, sampler, tracking, track_every,
                      replay_nice_increment, replay_write_nice_increment, mapper, photo_features,
                      photo_feature_options, photo_feature_side_px, model, ply, view, show_view)

}  // namespace sightmap::mapping
