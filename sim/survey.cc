#include "sim/survey.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <queue>
#include <set>
#include <utility>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::sim {
namespace {

double WrapDeg(double a) {
  a = std::fmod(a, 360.0);
  if (a > 180.0) a -= 360.0;
  if (a <= -180.0) a += 360.0;
  return a;
}

// The point of the closed polyline `loop` nearest to p, as arc length from loop[0].
double ArcOfNearest(const std::vector<Eigen::Vector2d>& loop, const Eigen::Vector2d& p) {
  double best_distance = std::numeric_limits<double>::infinity();
  double best_arc = 0.0;
  double arc = 0.0;
  for (size_t i = 0; i < loop.size(); ++i) {
    const Eigen::Vector2d& a = loop[i];
    const Eigen::Vector2d& b = loop[(i + 1) % loop.size()];
    const Eigen::Vector2d ab = b - a;
    const double length = ab.norm();
    const double u = length > 0.0 ? std::clamp((p - a).dot(ab) / (length * length), 0.0, 1.0) : 0.0;
    const double distance = (a + u * ab - p).norm();
    if (distance < best_distance) {
      best_distance = distance;
      best_arc = arc + u * length;
    }
    arc += length;
  }
  return best_arc;
}

// Corner cutting (two points replace each corner, at most `reach_m` from it), endpoints kept: a
// walker rounds corners instead of turning on the spot.
std::vector<Eigen::Vector2d> RoundCorners(const std::vector<Eigen::Vector2d>& path, double reach_m,
                                          int passes) {
  std::vector<Eigen::Vector2d> current = path;
  for (int pass = 0; pass < passes && current.size() > 2; ++pass) {
    std::vector<Eigen::Vector2d> next{current.front()};
    for (size_t i = 1; i + 1 < current.size(); ++i) {
      const Eigen::Vector2d& corner = current[i];
      for (const Eigen::Vector2d& neighbour : {current[i - 1], current[i + 1]}) {
        const double length = (neighbour - corner).norm();
        if (length < 1e-9) continue;
        next.push_back(corner + (neighbour - corner) * std::min(0.25, reach_m / length));
      }
    }
    next.push_back(current.back());
    current = std::move(next);
  }
  return current;
}

}  // namespace

bool SurveyOptions::Check(std::string* error) const {
  if (standpoints_per_appliance < 1 || standpoints_per_appliance > 12) {
    *error = "standpoints_per_appliance must be in [1, 12]";
    return false;
  }
  if (spread_deg < 0.0 || spread_deg > 90.0) {
    *error = "spread_deg must be in [0, 90]";
    return false;
  }
  if (!(min_distance_m > 0.0 && min_distance_m < max_distance_m)) {
    *error = "need 0 < min_distance_m < max_distance_m";
    return false;
  }
  for (const double d : {distance_m, overhead_distance_m}) {
    if (d < min_distance_m || d > max_distance_m) {
      *error = "distance_m and overhead_distance_m must lie in [min_distance_m, max_distance_m]";
      return false;
    }
  }
  if (eye_height_m <= 0.5 || eye_height_m > 2.2 || overhead_min_height_m <= 0.0) {
    *error = "eye_height_m must be in (0.5, 2.2] and overhead_min_height_m positive";
    return false;
  }
  if (max_elevation_deg <= 0.0 || max_elevation_deg > 90.0) {
    *error = "max_elevation_deg must be in (0, 90]";
    return false;
  }
  if (clearance_m < 0.05 || clearance_m > 1.0 || grid_m < 0.02 || grid_m > clearance_m) {
    *error = "need clearance_m in [0.05, 1] and grid_m in [0.02, clearance_m]";
    return false;
  }
  return true;
}

FloorGrid::FloorGrid(const Scene& scene, double cell_m, double clearance_m) : cell_m_(cell_m) {
  SIGHTMAP_CHECK(cell_m > 0.0 && clearance_m >= 0.0, "floor grid: bad cell size or clearance");
  SIGHTMAP_CHECK(!scene.rooms.empty(), "the scene has no rooms to walk through");
  Eigen::AlignedBox2d bounds;
  for (const Room& room : scene.rooms) bounds.extend(room.min).extend(room.max);
  origin_ = bounds.min();
  width_ = static_cast<int>(std::ceil(bounds.sizes().x() / cell_m));
  height_ = static_cast<int>(std::ceil(bounds.sizes().y() / cell_m));
  free_.assign(static_cast<size_t>(width_) * height_, 0);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      free_[Index(x, y)] = scene.RoomAt(CentreOf(x, y)) != nullptr;
    }
  }
  // A box blocks the cells within the clearance of its footprint when it reaches into the
  // walker's height: above ankle height (0.05 m: rugs and papers are walked over) and below head
  // clearance (1.9 m: lights and projectors are walked under).
  auto block = [&](const SceneBox& box) {
    if (box.center.z() + 0.5 * box.size.z() < 0.05 || box.center.z() - 0.5 * box.size.z() > 1.9) {
      return;
    }
    const double reach = 0.5 * box.size.head<2>().norm() + clearance_m;
    const Eigen::Vector2i lo = CellOf(box.center.head<2>() - Eigen::Vector2d::Constant(reach));
    const Eigen::Vector2i hi = CellOf(box.center.head<2>() + Eigen::Vector2d::Constant(reach));
    const Eigen::Rotation2Dd box_from_world(-box.yaw_rad);
    const Eigen::Vector2d half = 0.5 * box.size.head<2>() + Eigen::Vector2d::Constant(clearance_m);
    for (int y = std::max(lo.y(), 0); y <= std::min(hi.y(), height_ - 1); ++y) {
      for (int x = std::max(lo.x(), 0); x <= std::min(hi.x(), width_ - 1); ++x) {
        const Eigen::Vector2d local = box_from_world * (CentreOf(x, y) - box.center.head<2>());
        if (std::abs(local.x()) <= half.x() && std::abs(local.y()) <= half.y()) {
          free_[Index(x, y)] = 0;
        }
      }
    }
  };
  for (const SceneBox& box : scene.boxes) block(box);
  for (const Appliance& appliance : scene.appliances) {
    for (const SceneBox& box : appliance.boxes) block(box);
  }
}

Eigen::Vector2i FloorGrid::CellOf(const Eigen::Vector2d& p) const {
  return Eigen::Vector2i(static_cast<int>(std::floor((p.x() - origin_.x()) / cell_m_)),
                         static_cast<int>(std::floor((p.y() - origin_.y()) / cell_m_)));
}

Eigen::Vector2d FloorGrid::CentreOf(int x, int y) const {
  return origin_ + cell_m_ * Eigen::Vector2d(x + 0.5, y + 0.5);
}

bool FloorGrid::IsFree(const Eigen::Vector2d& p) const {
  const Eigen::Vector2i c = CellOf(p);
  if (c.x() < 0 || c.y() < 0 || c.x() >= width_ || c.y() >= height_) return false;
  return free_[Index(c.x(), c.y())] != 0;
}

std::optional<Eigen::Vector2d> FloorGrid::NearestFree(const Eigen::Vector2d& p) const {
  if (IsFree(p)) return p;
  const Eigen::Vector2i c = CellOf(p);
  const int reach = static_cast<int>(std::ceil(2.0 / cell_m_));
  std::optional<Eigen::Vector2d> best;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int y = c.y() - reach; y <= c.y() + reach; ++y) {
    for (int x = c.x() - reach; x <= c.x() + reach; ++x) {
      if (x < 0 || y < 0 || x >= width_ || y >= height_ || !free_[Index(x, y)]) continue;
      const double distance = (CentreOf(x, y) - p).norm();
      if (distance < best_distance && distance <= 2.0) {
        best_distance = distance;
        best = CentreOf(x, y);
      }
    }
  }
  return best;
}

bool FloorGrid::StraightIsFree(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  const double length = (b - a).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(length / (0.25 * cell_m_))));
  for (int i = 0; i <= steps; ++i) {
    if (!IsFree(a + (b - a) * (static_cast<double>(i) / steps))) return false;
  }
  return true;
}

std::vector<Eigen::Vector2d> FloorGrid::ShortestPath(const Eigen::Vector2d& a,
                                                     const Eigen::Vector2d& b) const {
  SIGHTMAP_CHECK(IsFree(a) && IsFree(b), "floor path: (" << a.transpose() << ") or ("
                                                         << b.transpose() << ") is not free floor");
  const Eigen::Vector2i start = CellOf(a);
  const Eigen::Vector2i goal = CellOf(b);
  const size_t cells = free_.size();
  std::vector<double> cost(cells, std::numeric_limits<double>::infinity());
  std::vector<int> parent(cells, -1);
  auto heuristic = [&](int x, int y) {  // octile distance, admissible on the 8-grid
    const double dx = std::abs(x - goal.x()), dy = std::abs(y - goal.y());
    return (dx + dy) + (std::sqrt(2.0) - 2.0) * std::min(dx, dy);
  };
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
  cost[Index(start.x(), start.y())] = 0.0;
  open.emplace(heuristic(start.x(), start.y()), Index(start.x(), start.y()));
  const int goal_index = Index(goal.x(), goal.y());
  while (!open.empty()) {
    const auto [f, index] = open.top();
    open.pop();
    if (index == goal_index) break;
    const int x = index % width_, y = index / width_;
    if (f - heuristic(x, y) > cost[index] + 1e-9) continue;  // a stale entry
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= width_ || ny >= height_) continue;
        const int next = Index(nx, ny);
        if (!free_[next]) continue;
        // No corner cutting between two blocked cells.
        if (dx != 0 && dy != 0 && (!free_[Index(x + dx, y)] || !free_[Index(x, y + dy)])) {
          continue;
        }
        const double step = (dx != 0 && dy != 0) ? std::sqrt(2.0) : 1.0;
        if (cost[index] + step < cost[next]) {
          cost[next] = cost[index] + step;
          parent[next] = index;
          open.emplace(cost[next] + heuristic(nx, ny), next);
        }
      }
    }
  }
  SIGHTMAP_CHECK(std::isfinite(cost[goal_index]),
                 "no walkable floor joins (" << a.transpose() << ") and (" << b.transpose()
                                             << "): check the scene's rooms, doors and boxes");
  std::vector<Eigen::Vector2d> cells_path;
  for (int index = goal_index; index != -1; index = parent[index]) {
    cells_path.push_back(CentreOf(index % width_, index / width_));
  }
  std::reverse(cells_path.begin(), cells_path.end());
  cells_path.front() = a;
  cells_path.back() = b;
  // String pulling: from each kept point, jump to the furthest point still in straight sight.
  std::vector<Eigen::Vector2d> path{a};
  size_t from = 0;
  while (from + 1 < cells_path.size()) {
    size_t to = from + 1;
    for (size_t k = cells_path.size() - 1; k > from + 1; --k) {
      if (StraightIsFree(cells_path[from], cells_path[k])) {
        to = k;
        break;
      }
    }
    path.push_back(cells_path[to]);
    from = to;
  }
  return path;
}

namespace {

// Where one appliance can be stood at and looked at from: ChooseStandpoints' probe.
class StandpointProbe {
 public:
  StandpointProbe(const Scene& scene, const FloorGrid& grid, const Appliance& appliance,
                  const SurveyOptions& options)
      : scene_(scene),
        grid_(grid),
        appliance_(appliance),
        options_(options),
        target_(appliance.points.front()),
        room_(scene.RoomAt(target_.head<2>())),
        preferred_m_(target_.z() > options.overhead_min_height_m ? options.overhead_distance_m
                                                                 : options.distance_m),
        min_distance_m_(std::max(
            options.min_distance_m,
            (target_.z() - options.eye_height_m) / std::tan(DegToRad(options.max_elevation_deg)))),
        plain_(PlainBoxNames(scene)) {}

  const Eigen::Vector3d& target() const { return target_; }
  const Room* room() const { return room_; }
  // Whether a standpoint needs its view clear beside the line of sight (see At).
  void RequireOpenView(bool required) { open_view_required_ = required; }

  // The standpoint `distance` along `bearing_deg` from the appliance, when it is one: free floor
  // in the appliance's room, no closer than the elevation limit allows, with a clear line of
  // sight at eye height and (when required) nothing within 0.8 m 12 deg to either side of it: a
  // view grazing a wall or half filled by a cupboard beside the walker is one the tracker loses.
  std::optional<Eigen::Vector2d> At(double bearing_deg, double distance) const {
    if (distance < min_distance_m_) return std::nullopt;
    const double a = DegToRad(bearing_deg);
    const Eigen::Vector2d p =
        target_.head<2>() + distance * Eigen::Vector2d(std::cos(a), std::sin(a));
    if (!grid_.IsFree(p) || (room_ != nullptr && scene_.RoomAt(p) != room_)) return std::nullopt;
    const Eigen::Vector3d eye(p.x(), p.y(), options_.eye_height_m);
    const Eigen::Vector3d ray = target_ - eye;
    if (scene_.Raycast(eye, ray.normalized(), ray.norm() - 0.05, appliance_.id)) {
      return std::nullopt;
    }
    for (const double side : {DegToRad(-12.0), DegToRad(12.0)}) {
      if (!open_view_required_) break;
      const Eigen::Vector3d aside = Eigen::AngleAxisd(side, Eigen::Vector3d::UnitZ()) * ray;
      if (scene_.Raycast(eye, aside.normalized(), std::min(0.8, ray.norm() - 0.3), appliance_.id)) {
        return std::nullopt;
      }
    }
    return p;
  }

  // Along a bearing, the standpoint nearest to the preferred distance (cheap: for the open arc).
  std::optional<Eigen::Vector2d> Nearest(double bearing_deg) const {
    std::optional<Eigen::Vector2d> best;
    double best_offset = std::numeric_limits<double>::infinity();
    for (double d = options_.min_distance_m; d <= options_.max_distance_m + 1e-9; d += 0.25) {
      if (std::abs(d - preferred_m_) >= best_offset) continue;
      if (const auto p = At(bearing_deg, d)) {
        best = p;
        best_offset = std::abs(d - preferred_m_);
      }
    }
    return best;
  }

  // Along a bearing, the standpoint with the richest view of the appliance's surroundings
  // (ViewScore, plain surfaces as bare as walls) less 2 per metre from the preferred distance: a
  // thermostat on a bare wall is better surveyed from a step further back, with a door frame or a
  // desk in view, than from where only the wall shows.
  std::optional<Eigen::Vector2d> Richest(double bearing_deg) const {
    std::optional<Eigen::Vector2d> best;
    double best_score = -std::numeric_limits<double>::infinity();
    for (double d = options_.min_distance_m; d <= options_.max_distance_m + 1e-9; d += 0.25) {
      const std::optional<Eigen::Vector2d> p = At(bearing_deg, d);
      if (!p) continue;
      const Eigen::Vector3d eye(p->x(), p->y(), options_.eye_height_m);
      const Eigen::Vector2d to = target_.head<2>() - *p;
      const double score = ViewScore(scene_, eye, std::atan2(to.y(), to.x()), &plain_) -
                           2.0 * std::abs(d - preferred_m_);
      if (score > best_score) {
        best_score = score;
        best = p;
      }
    }
    return best;
  }

 private:
  const Scene& scene_;
  const FloorGrid& grid_;
  const Appliance& appliance_;
  const SurveyOptions& options_;
  Eigen::Vector3d target_;
  const Room* room_;
  double preferred_m_;
  double min_distance_m_;
  std::set<std::string> plain_;
  bool open_view_required_ = true;
};

struct OpenArc {
  double front_deg = 0.0;
  double arc_deg = 360.0;
  bool all_around = true;
};

// The widest run of bearings (5 deg steps) that have a standpoint, and its middle: the
// appliance's front. Open all around (a ceiling light, a floor lamp in the open), the front faces
// the room's middle. Standpoints with an open view are asked for first, any when none has one.
OpenArc FindOpenArc(StandpointProbe* probe, const std::string& name) {
  constexpr int kBearings = 72;
  std::vector<bool> open(kBearings);
  int open_count = 0;
  for (const bool required : {true, false}) {
    probe->RequireOpenView(required);
    for (int i = 0; i < kBearings; ++i) {
      open[i] = probe->Nearest(i * 5.0).has_value();
      open_count += open[i];
    }
    if (open_count > 0) break;
  }
  SIGHTMAP_CHECK(open_count > 0,
                 "appliance " << name << " cannot be seen from any free floor 1-4 m away");
  OpenArc arc;
  if (open_count < kBearings) {
    int best_start = 0, best_length = 0;
    for (int start = 0; start < kBearings; ++start) {
      if (!open[start] || open[(start + kBearings - 1) % kBearings]) continue;
      int length = 0;
      while (length < kBearings && open[(start + length) % kBearings]) ++length;
      if (length > best_length) {
        best_length = length;
        best_start = start;
      }
    }
    arc.all_around = false;
    arc.arc_deg = 5.0 * (best_length - 1);
    arc.front_deg = 5.0 * best_start + 0.5 * arc.arc_deg;
  } else if (const Room* room = probe->room()) {
    const Eigen::Vector2d to_middle = 0.5 * (room->min + room->max) - probe->target().head<2>();
    if (to_middle.norm() > 0.1) {
      arc.front_deg = RadToDeg(std::atan2(to_middle.y(), to_middle.x()));
    }
  }
  return arc;
}

// The bearing nearest to `wanted_deg` (within `half_width_deg` of the front, searching outwards
// in 5 deg steps) that has a standpoint, with its richest standpoint.
std::optional<std::pair<double, Eigen::Vector2d>> NearestOpenBearing(const StandpointProbe& probe,
                                                                     double wanted_deg,
                                                                     double front_deg,
                                                                     double half_width_deg) {
  for (int step = 0; step <= 18; ++step) {
    for (const int sign : {1, -1}) {
      const double bearing = wanted_deg + sign * 5.0 * step;
      if (std::abs(WrapDeg(bearing - front_deg)) > half_width_deg + 1e-9) continue;
      if (const std::optional<Eigen::Vector2d> p = probe.Richest(bearing)) {
        return std::make_pair(bearing, *p);
      }
    }
  }
  return std::nullopt;
}

}  // namespace

Standpoints ChooseStandpoints(const Scene& scene, const FloorGrid& grid, const Appliance& appliance,
                              const SurveyOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(!appliance.points.empty(), "appliance " << appliance.name << " has no point");
  StandpointProbe probe(scene, grid, appliance, options);
  const OpenArc arc = FindOpenArc(&probe, appliance.name);
  // Standpoints keep 25 deg from the open arc's ends: a view grazing the wall an appliance hangs
  // on shows mostly wall.
  const double margin_deg = !arc.all_around && arc.arc_deg > 60.0 ? 25.0 : 0.0;
  const double usable_deg = arc.all_around ? 360.0 : arc.arc_deg - 2.0 * margin_deg;
  const int n = options.standpoints_per_appliance;
  const double spread =
      n > 1 ? std::min(options.spread_deg, usable_deg / static_cast<double>(n - 1)) : 0.0;
  Standpoints result;
  result.front_deg = WrapDeg(arc.front_deg);
  result.open_arc_deg = arc.all_around ? 360.0 : arc.arc_deg;
  for (int k = 0; k < n; ++k) {
    const double wanted = arc.front_deg + (k - 0.5 * (n - 1)) * spread;
    const auto found = NearestOpenBearing(probe, wanted, arc.front_deg, 0.5 * usable_deg);
    if (!found) continue;
    const bool repeated =
        std::any_of(result.stops.begin(), result.stops.end(),
                    [&](const SurveyStop& s) { return (s.position - found->second).norm() < 0.3; });
    if (repeated) continue;
    SurveyStop stop;
    stop.position = found->second;
    stop.target = probe.target();
    stop.appliance_id = appliance.id;
    stop.room = probe.room() != nullptr ? probe.room()->name : "";
    stop.bearing_deg = WrapDeg(found->first);
    result.stops.push_back(stop);
  }
  return result;
}

std::vector<SurveyStop> OrderStops(const Scene& scene, const FloorGrid& grid,
                                   std::vector<SurveyStop> stops) {
  SIGHTMAP_CHECK(scene.tour.size() >= 3, "the scene's tour needs at least 3 points");
  // Rooms in the order the tour first comes near one of their stops: each is surveyed in one
  // visit.
  std::map<std::string, double> room_arc;
  for (const SurveyStop& stop : stops) {
    const double arc = ArcOfNearest(scene.tour, stop.position);
    const auto [it, inserted] = room_arc.emplace(stop.room, arc);
    if (!inserted) it->second = std::min(it->second, arc);
  }
  std::vector<std::pair<double, std::string>> rooms;
  for (const auto& [name, arc] : room_arc) rooms.emplace_back(arc, name);
  std::sort(rooms.begin(), rooms.end());

  std::vector<SurveyStop> ordered;
  Eigen::Vector2d from = scene.tour.front();
  for (const auto& room_entry : rooms) {
    const std::string& name = room_entry.second;  // a plain reference: lambdas capture it
    const auto room = std::find_if(scene.rooms.begin(), scene.rooms.end(),
                                   [&](const Room& r) { return r.name == name; });
    const Eigen::Vector2d centre = room != scene.rooms.end() ? 0.5 * (room->min + room->max) : from;
    std::vector<SurveyStop> mine;
    for (const SurveyStop& stop : stops) {
      if (stop.room == name) mine.push_back(stop);
    }
    // Around the room (by bearing from its centre), starting where and turning the way that walks
    // least from where the walker comes from to the room's middle.
    auto bearing = [&](const SurveyStop& stop) {
      return std::atan2(stop.position.y() - centre.y(), stop.position.x() - centre.x());
    };
    std::stable_sort(mine.begin(), mine.end(), [&](const SurveyStop& a, const SurveyStop& b) {
      return bearing(a) < bearing(b);
    });
    std::optional<Eigen::Vector2d> middle;
    if (room != scene.rooms.end()) {
      middle = grid.NearestFree(centre);
      if (middle && scene.RoomAt(*middle) != &*room) middle.reset();
    }
    const size_t n = mine.size();
    std::vector<SurveyStop> best;
    double best_length = std::numeric_limits<double>::infinity();
    for (size_t first = 0; first < n; ++first) {
      for (const int direction : {1, -1}) {
        std::vector<SurveyStop> walk;
        double length = 0.0;
        Eigen::Vector2d at = from;
        for (size_t k = 0; k < n; ++k) {
          const long signed_n = static_cast<long>(n);
          const long step =
              (static_cast<long>(first) + direction * static_cast<long>(k)) % signed_n;
          const size_t i = static_cast<size_t>(step < 0 ? step + signed_n : step);
          walk.push_back(mine[i]);
          length += (mine[i].position - at).norm();
          at = mine[i].position;
        }
        if (middle) length += (*middle - at).norm();
        if (length < best_length) {
          best_length = length;
          best = std::move(walk);
        }
      }
    }
    ordered.insert(ordered.end(), best.begin(), best.end());
    from = best.empty() ? from : best.back().position;
    if (middle) {
      // After the room's last standpoint, walk through its middle.
      SurveyStop walk_through;
      walk_through.position = *middle;
      walk_through.room = name;
      ordered.push_back(walk_through);
      from = *middle;
    }
  }
  return ordered;
}

SurveyPlan PlanSurvey(const Scene& scene, const SurveyOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(!scene.appliances.empty(), "the scene has no appliances to survey");
  const FloorGrid grid(scene, options.grid_m, options.clearance_m);
  std::vector<SurveyStop> stops;
  for (const Appliance& appliance : scene.appliances) {
    const Standpoints mine = ChooseStandpoints(scene, grid, appliance, options);
    stops.insert(stops.end(), mine.stops.begin(), mine.stops.end());
  }
  SurveyPlan plan;
  plan.stops = OrderStops(scene, grid, std::move(stops));
  plan.path.push_back(plan.stops.front().position);
  for (size_t i = 0; i < plan.stops.size(); ++i) {
    plan.stops[i].arc_m = plan.length_m;
    const Eigen::Vector2d& to = plan.stops[(i + 1) % plan.stops.size()].position;
    const std::vector<Eigen::Vector2d> straight = grid.ShortestPath(plan.stops[i].position, to);
    std::vector<Eigen::Vector2d> leg = RoundCorners(straight, 0.3, 2);
    for (size_t k = 1; k < leg.size(); ++k) {
      if (!grid.StraightIsFree(leg[k - 1], leg[k])) {
        leg = straight;  // a corner too tight to round without touching a box
        break;
      }
    }
    for (size_t k = 1; k < leg.size(); ++k) {
      plan.length_m += (leg[k] - plan.path.back()).norm();
      plan.path.push_back(leg[k]);
    }
  }
  return plan;
}

}  // namespace sightmap::sim
