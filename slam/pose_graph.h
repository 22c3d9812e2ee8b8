// An SE(3) pose graph: camera poses joined by relative-pose measurements (odometry between
// consecutive keyframes, loop closures and relocalisations between distant ones), optimised by
// Ceres (Levenberg-Marquardt, sparse Cholesky) over quaternion + translation parameters, as in
// Ceres' examples/slam/pose_graph_3d. Ceres stays in pose_graph.cc.
//
// Residual of an edge (from, to, to_in_from = M, information = W). With the estimate
// E = world_from_from^-1 * world_from_to, the error is the 6-vector r = (t, w) for which
//   E = Exp(r) * M,  Exp(t, w) = [R(w) | t]  (R(w): the rotation of angle |w| about w / |w|),
// i.e. r = (t_E - R(w) t_M, AngleAxis(R_E R_M^T)): translation first, then a rotation applied
// on the left. That is the parameterisation RegistrationResult::information is computed in
// (slam/registration.h), so a registration's target_from_source and information are an edge's
// to_in_from and information with from = target and to = source. The cost of the edge is
// r^T W r (the chi-square of a 6-dof error when W is the inverse covariance); Ceres is given
// S r with S^T S = W.
//
// Loop edges (IsLoopEdge) get a Cauchy loss (odometry edges too, when odometry_loss_scale is
// set), and after each solve the loop edge with the largest chi-square above
// PoseGraphOptions::max_loop_chi2 is switched off and the graph solved again from the poses it
// had when Optimize() was called, until every active loop edge passes.
// Odometry edges are trusted and never switched off. Switched-off edges stay off in later calls
// (they are not re-checked: an edge that flips in and out would make the map jump) until the
// caller turns them back on with SetEdgeActive().
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>

#include "core/link_type.h"

namespace sightmap::slam {

struct PoseGraphOptions {
  // Bounds of each solve; Optimize() solves once plus once per switched-off edge.
  int max_iterations = 100;
  double max_solver_time_s = 0.5;  // per solve [s]
  int num_threads = 1;
  // A solve stops when an iteration lowers the cost by less than this fraction. With Cauchy losses
  // and a large correction, LM creeps over the last digits: on a 600 s walk, 1e-10 took 2-3 times
  // the iterations of 1e-6 (Ceres' default) and moved no keyframe by more than 0.1 mm.
  double function_tolerance = 1e-6;

  // Scale a of the Cauchy loss on loop edges, in units of the whitened residual |S r| (sigmas):
  // an edge with chi-square s is weighted by 1 / (1 + s / a^2). With a^2 = 22.46 a consistent
  // loop (s ~ 6 on average) keeps ~80% of its weight, while a false one (s in the thousands)
  // pulls with a force that falls as 1 / |S r| and cannot bend the map far before it is
  // switched off by the test below (4.74 = sqrt(22.46), the default max_loop_chi2). A correct
  // loop still closes from far away (one lap of 40 noisy steps: chi-square 2967 at the start).
  double loop_loss_scale = 4.74;
  // The same for odometry edges; 0 (the default) gives them a plain squared loss. See
  // MapperOptions::pose_graph for why the mapper uses one.
  double odometry_loss_scale = 0.0;

  // After a solve, an active loop edge whose chi-square r^T W r exceeds this is inconsistent
  // with the rest of the graph. 22.46 is the 99.9% quantile of the chi-square distribution with
  // 6 degrees of freedom: with honest informations a correct loop is switched off once in a
  // thousand, while a false loop tens of cm / degrees off scores in the thousands. Informations
  // that are overconfident (e.g. a registration's point-count information, which ignores
  // correlated depth errors) should be scaled down by the caller, not this threshold raised:
  // odometry claiming sigmas 10x smaller than its noise leaves a correct loop at chi-square ~240
  // even in plain least squares, and it is switched off (pose_graph_test,
  // OverconfidentOdometryLosesTheLoop). Infinity turns the switch-off off.
  double max_loop_chi2 = 22.46;

  // Scale of the Cauchy loss on rotation priors (SetRotationPrior), in their sigmas: a prior 3
  // sigmas off keeps 31% of its weight, one 10 sigmas off 4%, so a wrong measurement among the
  // many of a stretch of keyframes cannot turn it.
  double rotation_prior_loss_scale = 2.0;
  // When a solve with rotation priors switches a loop off, solve again by the loops alone, name
  // the axes from that solution and solve with the priors from there; keep that when it switches
  // fewer loops off.
  bool retry_rejected_loops_without_priors = true;

  // OptimizeAroundSeeded's solves start far from their optimum (a part turned by tens of
  // degrees): their bounds. The 1 Hz robot walk (seed 1) took 205 iterations, 0.85 s.
  int seeded_max_iterations = 1000;
  double seeded_max_solver_time_s = 10.0;  // per solve [s]
  // Its seed that turns each part to the building's axes names a prior there only when its pose
  // lies within this of the naming [deg]: farther, the naming is a guess (a keyframe placed a
  // quarter turn off). Unbounded, 1 Hz hand-held seed 23 went from 0.089 to 0.102 m.
  double seeded_max_axes_deviation_deg = 30.0;
  // Then up to this many rounds of turning the rigid parts (poses joined by registered links) a
  // quarter turn where their blind links say so, within seeded_max_axes_deviation_deg
  // (TurnPartsToTheirBridges), each solved and kept while it fits better. 0: none.
  int seeded_max_turn_rounds = 4;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const PoseGraphOptions& options);
void from_json(const nlohmann::json& json, PoseGraphOptions& options);

// Odometry and priors hold the graph together (switching a prior off would split the map it
// bridges); every other link type is checked as a loop.
bool IsLoopEdge(LinkType type);

struct PoseGraphEdge {
  int64_t from = 0;  // pose ids
  int64_t to = 0;
  // Measured pose of `to` in `from`'s frame: world_from_from^-1 * world_from_to.
  Eigen::Isometry3d to_in_from = Eigen::Isometry3d::Identity();
  // Inverse covariance of the error r = (translation x, y, z, left rotation x, y, z) defined in
  // the header comment; symmetric positive semi-definite.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
  LinkType type = LinkType::kOdometry;
};

// A measurement of where pose `to` lies along a direction of pose `from` (two keyframes seeing one
// wall, slam/wall_ties.h): normal_in_from . (world_from_from^-1 * position of to) = offset_m,
// with sigma_m. Used, as rotation priors, in solves of whole parts, under a Cauchy loss.
struct PlaneTie {
  int64_t from = 0;
  int64_t to = 0;
  Eigen::Vector3d normal_in_from = Eigen::Vector3d::UnitZ();
  double offset_m = 0.0;
  double sigma_m = 0.03;
};

// An absolute measurement of a pose's rotation known up to the 24 ways of naming three orthogonal
// axes (ManhattanSymmetries): the camera sees the building's axes as `cam_from_axes`. The graph
// holds where those axes lie in the world (world_from_axes, one rotation for every prior: placed
// by the first prior's pose, then estimated with the poses in each solve of whole parts). At each
// solve the candidate world_from_axes * S * cam_from_axes^T nearest the pose's estimate is the
// measurement, when within `max_deviation_rad` of it (farther, which naming is meant is a
// guess); its error is the rotation vector of estimate * measured^T, with `sigma_rad` on each
// component.
struct RotationPrior {
  Eigen::Matrix3d cam_from_axes = Eigen::Matrix3d::Identity();
  double sigma_rad = 0.02;
  double max_deviation_rad = 0.5;
};

struct PoseGraphSummary {
  // The last solve converged, or there was no active edge to solve for (false when it hit
  // max_iterations or max_solver_time_s: the poses are then the best found, still usable).
  bool converged = false;
  bool usable = true;  // false when Ceres failed: the poses were left as they were
  int solves = 0;      // 1 + one per switched-off edge (0 when there was nothing to solve)
  int iterations = 0;  // summed over the solves
  // Ceres' cost 0.5 * sum rho(r^T W r) at the start of the first solve and the end of the last
  // one (the first may still include edges that were switched off later).
  double initial_cost = 0.0;
  double final_cost = 0.0;
  double time_s = 0.0;  // wall time of the whole call
  // Indices (into PoseGraph::Edges()) of the loop edges switched off by this call, in order.
  std::vector<size_t> rejected_edges;
  // OptimizeNear kept a window's solution (the rest of the part did not move).
  bool local = false;
  // OptimizeAroundSeeded kept the solution from the seed.
  bool seeded = false;
  // Ids of the poses the call moved (free in the last solve), in id order.
  std::vector<int64_t> moved_poses;
  // Chi-square of each edge with the final poses (0 for inactive edges), by edge index.
  std::vector<double> edge_chi2;
};

// The covariance of an edge's error r with standard deviation sigma_m on each translation and
// sigma_rad on each rotation, uncorrelated [m], [rad].
Matrix6d DiagonalCovariance(double sigma_m, double sigma_rad);

// The inverse of a covariance or an information matrix, symmetrised, with `ridge` added to the
// diagonal first: an information singular along a degenerate direction (a bare wall) then gives
// a covariance of 1/ridge there, free for all practical purposes, instead of infinities.
Matrix6d RidgedInverse(const Matrix6d& matrix, double ridge);

// An information matrix whose covariance gets DiagonalCovariance(min_sigma_m, min_sigma_rad)
// added: no direction claims better than the floor. A singular information (degenerate geometry)
// is lifted by a tiny ridge before inverting, so the floor's addition leaves those directions
// free.
Matrix6d FlooredInformation(const Matrix6d& information, double min_sigma_m, double min_sigma_rad);

class PoseGraph {
 public:
  // Throws sightmap::Error on a duplicate id or a pose that is not a finite rigid transform.
  void AddPose(int64_t id, const Eigen::Isometry3d& world_from_cam);
  // Replaces the estimate of a known pose (throws when the id is unknown).
  void SetPose(int64_t id, const Eigen::Isometry3d& world_from_cam);
  // Returns the edge's index. Throws when an end is unknown, both ends are the same pose, the
  // measurement is not a finite rigid transform, or the information is not a finite symmetric
  // positive semi-definite matrix.
  size_t AddEdge(const PoseGraphEdge& edge);
  // Holds a pose still (the gauge). A connected component without a fixed pose holds its lowest
  // id, so Optimize() never has free gauge directions, whatever is fixed.
  void SetFixed(int64_t id, bool fixed = true);
  bool IsFixed(int64_t id) const;
  // Turns a switched-off edge back on (or any edge off).
  void SetEdgeActive(size_t index, bool active);
  // Replaces an edge's measurement and information (a motion-model guess revised once the motion
  // after it is measured); the poses move at the next optimisation. Throws as AddEdge does for a
  // bad measurement or information, or when the index is out of range, and then changes nothing.
  void SetEdgeMeasurement(size_t index, const Eigen::Isometry3d& to_in_from,
                          const Matrix6d& information);

  // Moves the poses to the least-squares estimate of the active edges. Poses without an active
  // edge do not move. Throws InvalidArgument on invalid options.
  PoseGraphSummary Optimize(const PoseGraphOptions& options = PoseGraphOptions());
  // The same over the part of the graph that active edges tie to pose `id` only: the rest has
  // no new edge and stays as it is. What a new link needs, at a cost that follows its part of
  // the map rather than the whole (a map of many unjoined segments).
  PoseGraphSummary OptimizeAround(int64_t id, const PoseGraphOptions& options = PoseGraphOptions());
  // OptimizeAround, and the same part solved twice more: from poses seeded by its edges alone
  // (SeedPoses: rotations by the chordal relaxation, then translations; the building's axes where
  // most rotation priors agree at the seed), and from a seed with the axes one more unknown and
  // each prior an edge to them, named at the better solution so far (within
  // seeded_max_axes_deviation_deg). Of the three, the solution that fits every edge the part had
  // and every prior (at its nearest naming, bound or not) best is kept. Earlier solves can leave
  // a stretch joined by weak edges turned where its priors no longer reach it; the seeds are
  // linear problems and do not depend on them.
  PoseGraphSummary OptimizeAroundSeeded(int64_t id,
                                        const PoseGraphOptions& options = PoseGraphOptions());
  // What a new edge (index `edge`) needs: OptimizeAround its end, but moving only the poses
  // within `hops` active edges of its ends when that fits the rest. Such a window is tried when
  // the edge closes a cycle inside it (else its correction belongs to a longer cycle), with the
  // rest of the part held, and kept when no active loop edge is then inconsistent (chi-square
  // above max_loop_chi2) and no edge at its border rose by more than `max_border_chi2_rise`.
  // Otherwise the window grows fourfold and is tried again, up to the whole part. A loop in the
  // middle of a revisit moves the poses near it, at a cost that does not grow with the map; the
  // first loop of a revisit bends as much of the map as it must.
  PoseGraphSummary OptimizeNear(size_t edge, int hops, double max_border_chi2_rise,
                                const PoseGraphOptions& options = PoseGraphOptions());

  // Gives pose `id` (which must exist) an absolute rotation measurement, replacing any it had.
  // Priors take part in solves of whole parts (Optimize, OptimizeAround, and OptimizeNear when
  // its window grows to the part), not in OptimizeNear's windows, and do not tie poses together:
  // a part of the map is still only what edges join. Throws on a non-rotation or a non-positive
  // sigma.
  void SetRotationPrior(int64_t id, const RotationPrior& prior);
  size_t NumRotationPriors() const { return rotation_priors_.size(); }
  // Replaces the plane ties (throws for a tie of an unknown pose or a non-positive sigma).
  void SetPlaneTies(std::vector<PlaneTie> ties);
  size_t NumPlaneTies() const { return plane_ties_.size(); }
  const std::vector<PlaneTie>& PlaneTies() const { return plane_ties_; }
  Eigen::Matrix3d WorldFromAxes() const { return world_from_axes_.toRotationMatrix(); }

  const Eigen::Isometry3d& Pose(int64_t id) const;  // throws when the id is unknown
  bool HasPose(int64_t id) const;
  size_t NumPoses() const { return nodes_.size(); }
  const std::vector<PoseGraphEdge>& Edges() const { return edges_; }
  bool EdgeActive(size_t index) const;  // throws when the index is out of range
  // r^T W r of an edge at the current poses, whether active or not.
  double EdgeChi2(size_t index) const;

  // How well the graph knows pose `to` relative to pose `from`: the covariance of that relative
  // pose (in an edge's parameterisation, r in `from`'s frame) chained along the path of active
  // edges between them whose summed covariance is smallest, each edge's covariance being
  // `edge_covariance(index)`; rotations are carried through the current poses, so a rotation's
  // uncertainty far back becomes translation uncertainty at `to`. The path's choice weighs an
  // edge's rotation variance by lever_m^2 against its translation variance. One path's covariance
  // bounds the graph's marginal one from above (other paths only tighten it), at the cost of a
  // Dijkstra search instead of a factorisation. nullopt when no active path joins them.
  std::optional<Eigen::Matrix<double, 6, 6>> PathCovariance(
      int64_t from, int64_t to,
      const std::function<Eigen::Matrix<double, 6, 6>(size_t edge)>& edge_covariance,
      double lever_m) const;
  // The same chained along `path` (FirmestPath's edges from `from`).
  Eigen::Matrix<double, 6, 6> PathCovariance(
      int64_t from, const std::vector<size_t>& path,
      const std::function<Eigen::Matrix<double, 6, 6>(size_t edge)>& edge_covariance) const;
  // The edges (indices into Edges(), in order from `from` to `to`) of that path: PathCovariance's
  // choice. Empty when from == to, nullopt when no active path joins them.
  std::optional<std::vector<size_t>> FirmestPath(
      int64_t from, int64_t to,
      const std::function<Eigen::Matrix<double, 6, 6>(size_t edge)>& edge_covariance,
      double lever_m) const;
  // Pose `id`'s rotation prior (SetRotationPrior), or null.
  const RotationPrior* RotationPriorOf(int64_t id) const;

 private:
  struct Node {
    Eigen::Isometry3d world_from_cam;
    bool fixed = false;
  };
  // What an optimisation covers: every active edge, or those active edges tie to pose `around`;
  // with `free`, only those poses move.
  struct Scope {
    std::optional<int64_t> around;
    std::optional<std::unordered_set<int64_t>> free;
    bool seeded = false;  // also solve from SeedPoses' seed; keep the better fit
  };
  // `before` (may be null) gets the poses it moved as they were; `border` (may be null) the edges
  // with one end free and one held, with their chi-square before (none: nothing was solved, the
  // window is its whole part).
  PoseGraphSummary OptimizeEdges(const PoseGraphOptions& options, const Scope& scope,
                                 std::map<int64_t, Eigen::Isometry3d>* before,
                                 std::vector<std::pair<size_t, double>>* border);
  // Throws unless the edge's measurement is a finite rigid transform and its information finite,
  // symmetric and positive semi-definite.
  void CheckMeasurement(const PoseGraphEdge& edge) const;
  // Whether a window's solution fits the rest of its part (see OptimizeNear).
  bool WindowFits(const PoseGraphSummary& summary,
                  const std::vector<std::pair<size_t, double>>& border, double max_border_chi2_rise,
                  double max_loop_chi2) const;

  std::map<int64_t, RotationPrior> rotation_priors_;  // by pose id
  std::vector<PlaneTie> plane_ties_;
  Eigen::Quaterniond world_from_axes_ = Eigen::Quaterniond::Identity();
  std::map<int64_t, Node> nodes_;  // by id: references stay valid, components find lowest ids
  std::vector<PoseGraphEdge> edges_;
  std::vector<bool> active_;
};

}  // namespace sightmap::slam
