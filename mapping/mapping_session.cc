#include "mapping/mapping_session.h"

#include <sys/resource.h>

#include <chrono>
#include <exception>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/statistics.h"
#include "mapping/bounded_queue.h"
#include "mapping/feature_conversion.h"
#include "slam/trajectory_eval.h"
#include "store/trajectory.h"

namespace sightmap::mapping {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

TimestampNs WallClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double PeakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // KiB on Linux
}

// A thread joined when it goes out of scope (no detached thread outlives the session).
class ScopedThread {
 public:
  ScopedThread() = default;
  template <typename Fn>
  explicit ScopedThread(Fn fn) : thread_(std::move(fn)) {}
  ScopedThread(ScopedThread&&) = default;
  ScopedThread& operator=(ScopedThread&& other) {
    Join();
    thread_ = std::move(other.thread_);
    return *this;
  }
  ~ScopedThread() { Join(); }
  void Join() {
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::thread thread_;
};

LinkType ToStore(MapperLinkType type) {
  switch (type) {
    case MapperLinkType::kOdometry:
      return LinkType::kOdometry;
    case MapperLinkType::kLoopClosure:
      return LinkType::kLoopClosure;
    case MapperLinkType::kRelocalisation:
      return LinkType::kRelocalisation;
    case MapperLinkType::kPrior:
      return LinkType::kPrior;
  }
  return LinkType::kOdometry;
}

MapperLinkType FromStore(LinkType type) {
  switch (type) {
    case LinkType::kOdometry:
      return MapperLinkType::kOdometry;
    case LinkType::kRelocalisation:
      return MapperLinkType::kRelocalisation;
    case LinkType::kPrior:
      return MapperLinkType::kPrior;
    case LinkType::kLoopClosure:
    case LinkType::kUser:  // a user's link constrains the graph like a verified loop
      return MapperLinkType::kLoopClosure;
  }
  return MapperLinkType::kLoopClosure;
}

// What SLAM hands the writer, in order.
struct WriteTask {
  enum class Kind { kKeyframe, kPoses, kVocabulary };
  Kind kind = Kind::kKeyframe;
  // kKeyframe: the record (links left empty) and its links with mapper ids at both ends.
  int64_t mapper_id = -1;
  KeyframeRecord record;
  std::vector<MapperLink> links;
  FeedStatus status;
  // kPoses: every optimised pose, by mapper id, and the stored links the optimisation switched off.
  std::vector<std::pair<int64_t, Eigen::Isometry3d>> poses;
  std::vector<MapperLink> deactivated;
  // kVocabulary: Vocabulary::Serialize()'s bytes.
  std::vector<uint8_t> vocabulary;
};

nlohmann::json OptionsJson(const MappingOptions& options) {
  nlohmann::json json;
  json["source"] = options.source;
  json["rate_hz"] = options.sampler.rate_hz;
  json["start_frame"] = options.start_frame;
  json["max_keyframes"] = options.max_keyframes;
  json["live"] = options.live;
  json["realtime"] = options.source_options.realtime;
  json["width"] = options.source_options.width;
  json["height"] = options.source_options.height;
  json["fps"] = options.source_options.fps;
  json["calibration_file"] = options.source_options.calibration_file;
  json["max_features"] = options.mapper.features.max_features;
  json["odometry_window"] = options.mapper.odometry_window;
  json["vocabulary_training_keyframes"] = options.mapper.vocabulary_training_keyframes;
  json["loop_candidates"] = options.mapper.loop_candidates;
  return json;
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
  if (frame_queue_capacity < 1 || keyframe_queue_capacity < 1 || write_queue_capacity < 1) {
    *error = "queue capacities must be >= 1";
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

MappingSummary MappingSession::Run(std::ostream* notices) {
  MappingSummary summary;

  // The source first: without one, the model is not touched.
  std::unique_ptr<RgbdSource> source = OpenSource(options_.source, options_.source_options);
  const SourceMetadata meta = source->metadata();
  summary.source_kind = meta.kind;
  const bool live = options_.live || meta.kind == "openni";
  const Intrinsics camera = meta.intrinsics;
  // Said before the model is touched when the source has none at all; a folder whose ground truth
  // has gaps fails at the first frame without it.
  const auto no_ground_truth = [](const std::string& what) {
    return Error(
        "--ground-truth-poses needs a source with ground truth (the simulator, or a TUM folder "
        "with groundtruth.txt); " +
        what + " has none");
  };
  if (options_.ground_truth_poses && !meta.has_ground_truth) {
    throw no_ground_truth("this " + meta.kind + " source");
  }

  std::unique_ptr<MapViewFeed> view;
  if (options_.show_view) {
    MapViewFeedOptions view_options = options_.view;
    // A map anchored to the source's ground truth is in the scene's frame, whose up is +z (the
    // simulator's building, TUM's motion capture), not the first camera's -y: the floor plan was
    // a side view of the building.
    if (options_.anchor_to_ground_truth && meta.has_ground_truth) {
      view_options.world_up = Eigen::Vector3d::UnitZ();
    }
    view = MapViewFeed::Create(view_options, notices);
  }

  Model model = Model::Open(options_.model_path, options_.model);
  // Owned apart so that its memory (features, depth and the graph of every keyframe) is freed
  // before the PLY export, which reads the model: a 3,000-keyframe run would hold both at once.
  auto mapper_owner = std::make_unique<Mapper>(camera, options_.mapper);
  Mapper& mapper = *mapper_owner;

  // Mapper id -> store id. Filled by the restore below, then only by the writer thread.
  std::vector<KeyframeId> store_ids;
  std::vector<int64_t> restored_segment_members;  // one keyframe of each restored segment
  bool vocabulary_stored = false;
  // Sessions a crash left running (with or without keyframes) were interrupted.
  summary.interrupted_sessions_marked = model.MarkRunningSessionsInterrupted(WallClockNs());
  if (model.NumKeyframes() > 0) {
    summary.resumed = true;
    const std::vector<KeyframeInfo> stored = model.Keyframes();
    const Intrinsics& first = stored.front().intrinsics;
    SIGHTMAP_CHECK(first.width == camera.width && first.height == camera.height,
                   "the model " << options_.model_path << " was mapped with a " << first.width
                                << "x" << first.height << " camera but " << options_.source
                                << " delivers " << camera.width << "x" << camera.height
                                << " — map into a new model or use the same camera mode");
    if (auto vocabulary = model.LoadVocabulary()) {
      SIGHTMAP_CHECK(vocabulary->first == Vocabulary::kFormat,
                     "the model's vocabulary is of format '"
                         << vocabulary->first << "', this sightmap reads '" << Vocabulary::kFormat
                         << "' — map into a new model");
      mapper.SetVocabulary(
          std::make_shared<const Vocabulary>(Vocabulary::Deserialize(vocabulary->second)));
      vocabulary_stored = true;
    }
    std::map<int64_t, int64_t> mapper_id_of;  // store id -> mapper id
    for (const KeyframeInfo& info : stored) {
      const cv::Mat depth = model.LoadDepth(info.id);
      // The colour only when something uses it (a JPEG to decode per stored keyframe).
      const cv::Mat color =
          view || options_.mapper.dense_refinement ? model.LoadColor(info.id) : cv::Mat();
      const int64_t id =
          mapper.RestoreKeyframe(info.timestamp_ns, FromStoreFeatures(model.LoadFeatures(info.id)),
                                 depth, info.world_from_cam, color);
      SIGHTMAP_CHECK(id == static_cast<int64_t>(store_ids.size()),
                     "the mapper restored keyframe " << info.id.value() << " as " << id);
      store_ids.push_back(info.id);
      mapper_id_of[info.id.value()] = id;
      if (view) {
        view->AddKeyframe(id, static_cast<int>(info.session.value()), info.world_from_cam, color,
                          depth, info.intrinsics);
      }
    }
    for (const LinkRecord& record : model.Links()) {
      MapperLink link;
      link.from = mapper_id_of.at(record.from.value());
      link.to = mapper_id_of.at(record.to.value());
      link.from_from_to = record.from_from_to;
      link.information = record.information;
      link.type = FromStore(record.type);
      link.active = record.active;
      mapper.RestoreLink(link);
      if (view && link.active && link.type != MapperLinkType::kOdometry) {
        view->AddLoop(link.from, link.to);
      }
    }
    std::set<int> roots;
    for (int64_t id = 0; id < static_cast<int64_t>(store_ids.size()); ++id) {
      if (roots.insert(mapper.SegmentOf(id)).second) restored_segment_members.push_back(id);
    }
    mapper.StartNewSegment();
    summary.restored_keyframes = static_cast<int64_t>(store_ids.size());
    if (notices) {
      *notices << "resuming " << options_.model_path << ": " << store_ids.size() << " keyframes in "
               << roots.size() << " segment(s)"
               << (summary.interrupted_sessions_marked > 0
                       ? ", " + std::to_string(summary.interrupted_sessions_marked) +
                             " crashed session(s) marked interrupted"
                       : std::string())
               << "\n";
    }
  }

  SessionRecord session_record;
  session_record.start_time_ns = WallClockNs();
  session_record.source = options_.source;
  session_record.device_name = meta.device_name;
  session_record.device_serial = meta.serial;
  session_record.intrinsics = camera;
  session_record.options_json = OptionsJson(options_).dump();
  summary.session_number = static_cast<int64_t>(model.Sessions().size()) + 1;
  const SessionId session = model.BeginSession(session_record);
  summary.session = session.value();
  const int session_number = static_cast<int>(summary.session_number);
  if (view) summary.view = view->description();

  // Shared between the stages.
  BoundedQueue<RgbdFrame> frames(static_cast<size_t>(options_.frame_queue_capacity));
  BoundedQueue<KeyframeItem> keyframes(static_cast<size_t>(options_.keyframe_queue_capacity));
  BoundedQueue<WriteTask> writes(static_cast<size_t>(options_.write_queue_capacity));
  std::atomic<bool> capture_stop{false};
  std::atomic<int64_t> frames_read{0};
  std::atomic<int64_t> dropped{0};
  std::atomic<bool> capture_failed{false};
  std::string capture_error;  // written by the capture thread before it closes `frames`
  std::atomic<bool> writer_failed{false};
  std::exception_ptr writer_error;  // written by the writer thread before it sets writer_failed
  std::atomic<int64_t> committed{0};

  const Clock::time_point map_start = Clock::now();

  ScopedThread writer([&] {
    try {
      while (std::optional<WriteTask> task = writes.Pop()) {
        switch (task->kind) {
          case WriteTask::Kind::kKeyframe: {
            KeyframeRecord& record = task->record;
            for (const MapperLink& link : task->links) {
              LinkRecord stored;
              stored.from = link.from == task->mapper_id
                                ? KeyframeId()
                                : store_ids.at(static_cast<size_t>(link.from));
              stored.to = link.to == task->mapper_id ? KeyframeId()
                                                     : store_ids.at(static_cast<size_t>(link.to));
              stored.type = ToStore(link.type);
              stored.from_from_to = link.from_from_to;
              stored.information = link.information;
              stored.active = link.active;
              record.links.push_back(stored);
            }
            SIGHTMAP_CHECK(task->mapper_id == static_cast<int64_t>(store_ids.size()),
                           "keyframe " << task->mapper_id << " reached the writer out of order");
            store_ids.push_back(model.AddKeyframe(record));
            ++committed;
            if (view) {
              view->AddKeyframe(task->mapper_id, session_number, record.world_from_cam,
                                record.color, record.depth, record.intrinsics);
              for (const MapperLink& link : task->links) {
                if (link.active && link.type != MapperLinkType::kOdometry) {
                  view->AddLoop(link.from, link.to);
                }
              }
              view->SetCamera(record.world_from_cam);
              view->SetStatus(task->status);
            }
            break;
          }
          case WriteTask::Kind::kPoses: {
            std::vector<std::pair<KeyframeId, Eigen::Isometry3d>> poses;
            poses.reserve(task->poses.size());
            for (const auto& [id, pose] : task->poses) {
              if (id < static_cast<int64_t>(store_ids.size())) {
                poses.emplace_back(store_ids[static_cast<size_t>(id)], pose);
              }
            }
            std::vector<LinkKey> deactivated;
            for (const MapperLink& link : task->deactivated) {
              deactivated.push_back({store_ids.at(static_cast<size_t>(link.from)),
                                     store_ids.at(static_cast<size_t>(link.to)),
                                     ToStore(link.type)});
            }
            model.UpdateGraph(poses, deactivated);
            if (view) view->UpdatePoses(task->poses);
            break;
          }
          case WriteTask::Kind::kVocabulary:
            model.SetVocabulary(Vocabulary::kFormat, task->vocabulary);
            break;
        }
      }
    } catch (...) {
      writer_error = std::current_exception();
      writer_failed = true;
      writes.Close();
      frames.Close();
      keyframes.Close();
    }
  });

  // The tracker works with the mapper's features and depth, at the keyframe rate asked for.
  TrackStageOptions tracking = options_.tracking;
  tracking.track = tracking.track && !options_.ground_truth_poses;
  tracking.tracker.features = options_.mapper.features;
  tracking.tracker.registration = options_.mapper.registration;
  tracking.tracker.depth_downscale = options_.mapper.depth_downscale;
  tracking.tracker.keyframe_rate_hz = options_.sampler.rate_hz;
  // Without tracking only keyframes are needed, and the capture stage samples them itself so that
  // a live sensor drops keyframes the mapper cannot take, not frames in between.
  KeyframeSampler sampler(options_.sampler);
  const auto wanted = [&](const RgbdFrame& frame) {
    if (!tracking.track) return sampler.Accept(frame.timestamp_ns);
    return (frame.index - options_.start_frame) % options_.track_every == 0;
  };
  TrackStage track(camera, tracking, &frames, &keyframes);
  ScopedThread capture([&] {
    try {
      Clock::time_point last_live_image = Clock::now() - std::chrono::seconds(1);
      while (!capture_stop) {
        std::optional<RgbdFrame> frame = source->Next();
        if (!frame) break;
        ++frames_read;
        if (frame->index < options_.start_frame) continue;
        if (view && Clock::now() - last_live_image > std::chrono::milliseconds(100)) {
          view->SetLiveImages(frame->color, frame->depth);
          last_live_image = Clock::now();
        }
        if (view && view->paused()) {
          // Live: frames pass by unused. Replay: the recording waits for the user.
          if (live) continue;
          while (view->paused() && !capture_stop && !view->stop_requested()) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
          }
        }
        if (!wanted(*frame)) continue;
        if (live) {
          if (!frames.TryPush(std::move(*frame)) && !capture_stop) ++dropped;
        } else if (!frames.Push(std::move(*frame))) {
          break;
        }
      }
    } catch (const std::exception& e) {
      capture_error = e.what();
      capture_failed = true;
    }
    frames.Close();
  });

  // The SLAM stage, on this thread.
  std::vector<StampedPose> ground_truth;
  std::vector<int64_t> session_ids;
  std::vector<double> keyframe_s;  // mapping time of each keyframe
  int64_t links_rejected_after_commit = 0;
  bool vocabulary_sent = vocabulary_stored;
  bool joined = false;
  Clock::time_point last_progress = Clock::now();
  auto make_progress = [&] {
    MappingProgress progress;
    progress.keyframes = static_cast<int64_t>(session_ids.size());
    progress.model_keyframes = static_cast<int64_t>(mapper.NumKeyframes());
    progress.loops = mapper.NumLoopClosures();
    progress.dropped_frames = dropped;
    progress.frames_read = frames_read;
    if (meta.depth_frame_count) progress.frames_total = *meta.depth_frame_count;
    progress.tracking = mapper.tracking_state();
    progress.resumed = summary.resumed;
    progress.joined_stored_map = joined;
    progress.paused = view && view->paused();
    progress.elapsed_s = SecondsSince(map_start);
    progress.keyframes_per_s = progress.elapsed_s > 0.0
                                   ? static_cast<double>(progress.keyframes) / progress.elapsed_s
                                   : 0.0;
    return progress;
  };
  auto stop_requested = [&] {
    if (interrupt_flag_ && interrupt_flag_->load()) RequestStop(StopReason::kSignal);
    if (view && view->stop_requested()) RequestStop(StopReason::kUserStop);
    return stop_reason_.load() >= 0 || writer_failed.load();
  };

  std::exception_ptr slam_error;
  try {
    while (!stop_requested()) {
      KeyframeItem item;
      const auto popped = keyframes.Pop(&item, std::chrono::milliseconds(100));
      if (popped == BoundedQueue<KeyframeItem>::PopResult::kEnd) break;
      if (popped == BoundedQueue<KeyframeItem>::PopResult::kTimeout) {
        if (progress_ && SecondsSince(last_progress) > 1.0) {
          progress_(make_progress());
          last_progress = Clock::now();
        }
        continue;
      }
      RgbdFrame& frame = item.keyframe.frame;
      if (options_.ground_truth_poses && !frame.world_from_cam_gt) {
        throw no_ground_truth("the frame at " + std::to_string(frame.timestamp_ns) + " ns");
      }
      if (mapper.NumKeyframes() == 0 && options_.anchor_to_ground_truth &&
          frame.world_from_cam_gt) {
        mapper.SetFirstPose(*frame.world_from_cam_gt);
      }
      KeyframeReport report;
      if (options_.ground_truth_poses) {
        report = mapper.AddKeyframeAtPose(frame.timestamp_ns, frame.color, frame.depth,
                                          *frame.world_from_cam_gt);
      } else if (item.tracked) {
        // A copy: the images are shared, and `frame` is written to the model below.
        report = mapper.AddTrackedKeyframe(item.keyframe);
      } else {
        report = mapper.AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
      }
      keyframe_s.push_back(report.times.total_s);
      session_ids.push_back(report.id);
      if (frame.world_from_cam_gt) {
        ground_truth.push_back({frame.timestamp_ns, *frame.world_from_cam_gt});
      }
      if (summary.resumed && !joined) {
        const int root = mapper.SegmentOf(report.id);
        for (int64_t member : restored_segment_members) joined |= mapper.SegmentOf(member) == root;
      }

      WriteTask task;
      task.kind = WriteTask::Kind::kKeyframe;
      task.mapper_id = report.id;
      task.record.session = session;
      task.record.timestamp_ns = frame.timestamp_ns;
      task.record.world_from_cam = report.world_from_cam;
      task.record.odom_world_from_cam = report.world_from_cam;
      task.record.intrinsics = camera;
      task.record.color = std::move(frame.color);
      task.record.depth = std::move(frame.depth);
      task.record.features = ToStoreFeatures(mapper.FeaturesOf(report.id));
      // This step's links are the newest of Links(), stored with their state now (a loop the pose
      // graph switched off in this very step is stored inactive). Older links it switched off
      // were stored active and are switched off with the poses below.
      const std::vector<MapperLink>& links = mapper.Links();
      const size_t first_new = links.size() - report.new_links.size();
      for (size_t i = first_new; i < links.size(); ++i) task.links.push_back(links[i]);
      std::vector<MapperLink> deactivated;
      for (size_t index : report.rejected_links) {
        if (index < first_new) deactivated.push_back(links[index]);
      }
      links_rejected_after_commit += static_cast<int64_t>(deactivated.size());
      const MappingProgress progress = make_progress();
      task.status = FeedStatus{progress.model_keyframes, progress.loops, report.state,
                               progress.keyframes_per_s, progress.elapsed_s};
      if (!writes.Push(std::move(task))) break;  // the writer failed
      if (report.optimised) {
        WriteTask poses;
        poses.kind = WriteTask::Kind::kPoses;
        poses.deactivated = std::move(deactivated);
        const std::vector<StampedPose> trajectory = mapper.Trajectory();
        for (size_t id = 0; id < trajectory.size(); ++id) {
          poses.poses.emplace_back(static_cast<int64_t>(id), trajectory[id].world_from_cam);
        }
        if (!writes.Push(std::move(poses))) break;
      }
      if (!vocabulary_sent && mapper.vocabulary()) {
        WriteTask vocabulary;
        vocabulary.kind = WriteTask::Kind::kVocabulary;
        vocabulary.vocabulary = mapper.vocabulary()->Serialize();
        if (!writes.Push(std::move(vocabulary))) break;
        vocabulary_sent = true;
      }
      if (progress_) {
        progress_(progress);
        last_progress = Clock::now();
      }
      if (options_.max_keyframes > 0 &&
          static_cast<int64_t>(session_ids.size()) >= options_.max_keyframes) {
        RequestStop(StopReason::kMaxKeyframes);
      }
    }
  } catch (...) {
    slam_error = std::current_exception();
  }

  // Stop capturing; frames still queued are not mapped.
  capture_stop = true;
  frames.Close();
  frames.Clear();
  capture.Join();
  keyframes.Close();
  keyframes.Clear();
  track.Join();
  if (!slam_error && track.error()) slam_error = track.error();
  // Every pose as the mapper has it now, then the writer drains and ends.
  if (!slam_error && !writer_failed && !session_ids.empty()) {
    WriteTask poses;
    poses.kind = WriteTask::Kind::kPoses;
    const std::vector<StampedPose> trajectory = mapper.Trajectory();
    for (size_t id = 0; id < trajectory.size(); ++id) {
      poses.poses.emplace_back(static_cast<int64_t>(id), trajectory[id].world_from_cam);
    }
    writes.Push(std::move(poses));
  }
  writes.Close();
  writer.Join();

  if (stop_reason_.load() >= 0) {
    summary.reason = static_cast<StopReason>(stop_reason_.load());
  } else if (capture_failed) {
    summary.reason = StopReason::kSourceFailed;
    summary.reason_detail = capture_error;
  } else {
    summary.reason = StopReason::kSourceEnded;
  }
  const bool failed = slam_error || writer_failed;
  const SessionEnd end_state = failed || summary.reason == StopReason::kSourceFailed
                                   ? SessionEnd::kInterrupted
                                   : SessionEnd::kFinished;
  try {
    model.EndSession(session, end_state, WallClockNs());
  } catch (const Error&) {
    if (!failed) throw;  // the first failure is the one to report
  }
  if (view) view->Finish();
  if (slam_error) std::rethrow_exception(slam_error);
  if (writer_failed) std::rethrow_exception(writer_error);
  if (summary.reason == StopReason::kSourceFailed && session_ids.empty()) {
    SIGHTMAP_THROW(Error, capture_error);
  }

  if (progress_) {
    MappingProgress last = make_progress();
    last.finished = true;
    progress_(last);
  }
  summary.elapsed_s = SecondsSince(map_start);
  summary.keyframes = static_cast<int64_t>(session_ids.size());
  summary.keyframes_per_s =
      summary.elapsed_s > 0.0 ? static_cast<double>(summary.keyframes) / summary.elapsed_s : 0.0;
  summary.model_keyframes = model.NumKeyframes();
  summary.loops = mapper.NumLoopClosures();
  summary.segments = mapper.NumSegments();
  // Nothing writes to the model after this (the PLY and the trajectory only read it).
  const ModelSummary model_summary = model.Summary();
  summary.largest_segment_keyframes = model_summary.largest_segment_keyframes;
  summary.largest_part_ratio = model_summary.keyframes > 0
                                   ? static_cast<double>(model_summary.largest_segment_keyframes) /
                                         static_cast<double>(model_summary.keyframes)
                                   : 0.0;
  summary.prior_links = model_summary.prior_links;
  const TrackStageReport& tracked = track.report();
  summary.tracked_frames = tracking.track ? tracked.counters.frames : 0;
  summary.dense_frames = tracked.counters.dense;
  summary.blind_frames = tracked.counters.blind;
  summary.early_keyframes = tracked.counters.early_keyframes;
  summary.track_median_ms = 1e3 * Percentile(tracked.frame_s, 0.5);
  summary.track_p95_ms = 1e3 * Percentile(tracked.frame_s, 0.95);
  summary.keyframe_median_ms = 1e3 * Percentile(keyframe_s, 0.5);
  summary.keyframe_p95_ms = 1e3 * Percentile(keyframe_s, 0.95);
  summary.dropped_frames = dropped;
  summary.frames_read = frames_read;
  summary.links_rejected_after_commit = links_rejected_after_commit;
  summary.joined_stored_map = joined;

  if (ground_truth.size() >= 3 && ground_truth.size() == session_ids.size()) {
    std::vector<StampedPose> estimate;
    estimate.reserve(session_ids.size());
    for (size_t i = 0; i < session_ids.size(); ++i) {
      estimate.push_back({ground_truth[i].timestamp_ns, mapper.WorldFromCam(session_ids[i])});
    }
    try {
      const TrajectoryError error = EvaluateTrajectory(ground_truth, estimate);
      summary.ate_rmse_m = error.ate_rmse_m;
      summary.ate_max_m = error.ate_max_m;
      summary.ate_poses = error.matched_poses;
    } catch (const Error&) {
      // Too few poses to align: no ATE.
    }
  }

  // Nothing below uses the mapper or the view.
  mapper_owner.reset();
  view.reset();
  if (summary.model_keyframes > 0) {
    if (!options_.ply_path.empty()) {
      if (notices) {
        *notices << "writing " << options_.ply_path << " from " << summary.model_keyframes
                 << " keyframes\n"
                 << std::flush;
      }
      summary.ply_points = ExportPly(model, options_.ply_path, options_.ply).written_points;
      summary.ply_path = options_.ply_path;
    }
    if (!options_.trajectory_path.empty()) {
      WriteTumTrajectory(options_.trajectory_path, ModelTrajectory(model));
      summary.trajectory_path = options_.trajectory_path;
    }
  }
  summary.model_bytes = model_summary.size_bytes;
  summary.peak_rss_mib = PeakRssMiB();
  return summary;
}

}  // namespace sightmap::mapping
