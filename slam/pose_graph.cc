#include "slam/pose_graph.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <queue>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Eigenvalues>

#include "core/check.h"
#include "core/link_type.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "slam/manhattan_frame.h"
#include "slam/pose_graph_stages.h"
#include "slam/pose_seed.h"

namespace sightmap::slam {

bool IsLoopEdge(LinkType type) { return type != LinkType::kOdometry && type != LinkType::kPrior; }
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

bool IsRigid(const Eigen::Isometry3d& transform) {
  if (!transform.matrix().allFinite()) return false;
  const Eigen::Matrix3d rotation = transform.linear();
  return (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <
             1e-6 &&
         rotation.determinant() > 0.0;
}

// The edge error r = (t, w) with E = Exp(r) * M (see pose_graph.h), for the poses a = from and
// b = to given as unit quaternions (Eigen's x, y, z, w order) and positions in the world.
template <typename T>
Eigen::Matrix<T, 6, 1> EdgeError(const T* q_a_data, const T* p_a_data, const T* q_b_data,
                                 const T* p_b_data, const Eigen::Quaterniond& q_measured,
                                 const Eigen::Vector3d& p_measured) {
  const Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_data);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(p_a_data);
  const Eigen::Map<const Eigen::Quaternion<T>> q_b(q_b_data);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_b(p_b_data);
  const Eigen::Quaternion<T> q_a_inverse = q_a.conjugate();
  const Eigen::Quaternion<T> q_ab = q_a_inverse * q_b;
  const Eigen::Matrix<T, 3, 1> p_ab = q_a_inverse * (p_b - p_a);
  // R(w) = R_E R_M^T and t = t_E - R(w) t_M.
  const Eigen::Quaternion<T> q_delta = q_ab * q_measured.conjugate().template cast<T>();
  Eigen::Matrix<T, 6, 1> error;
  error.template head<3>() = p_ab - q_delta * p_measured.template cast<T>();
  const T q_delta_wxyz[4] = {q_delta.w(), q_delta.x(), q_delta.y(), q_delta.z()};
  ceres::QuaternionToAngleAxis(q_delta_wxyz, error.data() + 3);
  return error;
}

class EdgeCost {
 public:
  EdgeCost(const Eigen::Isometry3d& to_in_from, const Matrix6d& sqrt_information)
      : q_measured_(to_in_from.linear()),
        p_measured_(to_in_from.translation()),
        sqrt_information_(sqrt_information) {
    q_measured_.normalize();
  }

  template <typename T>
  bool operator()(const T* q_a, const T* p_a, const T* q_b, const T* p_b, T* residuals) const {
    Eigen::Map<Eigen::Matrix<T, 6, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() *
               EdgeError(q_a, p_a, q_b, p_b, q_measured_, p_measured_);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Isometry3d& to_in_from,
                                     const Matrix6d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<EdgeCost, 6, 4, 3, 4, 3>(
        new EdgeCost(to_in_from, sqrt_information));
  }

 private:
  Eigen::Quaterniond q_measured_;
  Eigen::Vector3d p_measured_;
  Matrix6d sqrt_information_;
};

// A rotation prior's error, whitened: the rotation vector of world_from_cam * measured^T / sigma,
// where measured = world_from_axes * axes_from_cam and world_from_axes is a parameter too.
class RotationPriorCost {
 public:
  RotationPriorCost(const Eigen::Matrix3d& axes_from_cam, double sigma_rad)
      : axes_from_cam_(Eigen::Quaterniond(axes_from_cam).normalized()),
        inverse_sigma_(1.0 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* q_data, const T* world_from_axes_data, T* residuals) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_data);
    const Eigen::Map<const Eigen::Quaternion<T>> world_from_axes(world_from_axes_data);
    const Eigen::Quaternion<T> delta =
        q * (world_from_axes * axes_from_cam_.template cast<T>()).conjugate();
    const T delta_wxyz[4] = {delta.w(), delta.x(), delta.y(), delta.z()};
    ceres::QuaternionToAngleAxis(delta_wxyz, residuals);
    for (int i = 0; i < 3; ++i) residuals[i] *= T(inverse_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Matrix3d& axes_from_cam, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<RotationPriorCost, 3, 4, 4>(
        new RotationPriorCost(axes_from_cam, sigma_rad));
  }

 private:
  Eigen::Quaterniond axes_from_cam_;
  double inverse_sigma_;
};

// A plane tie's error, whitened: (normal . (R_from^T (p_to - p_from)) - offset) / sigma.
class PlaneTieCost {
 public:
  PlaneTieCost(const Eigen::Vector3d& normal_in_from, double offset_m, double sigma_m)
      : normal_(normal_in_from), offset_m_(offset_m), inverse_sigma_(1.0 / sigma_m) {}

  template <typename T>
  bool operator()(const T* q_from_data, const T* p_from_data, const T* p_to_data,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_from(q_from_data);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_from(p_from_data);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_to(p_to_data);
    const Eigen::Matrix<T, 3, 1> in_from = q_from.conjugate() * (p_to - p_from);
    residual[0] = (normal_.cast<T>().dot(in_from) - T(offset_m_)) * T(inverse_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const PlaneTie& tie) {
    return new ceres::AutoDiffCostFunction<PlaneTieCost, 1, 4, 3, 3>(
        new PlaneTieCost(tie.normal_in_from, tie.offset_m, tie.sigma_m));
  }

 private:
  Eigen::Vector3d normal_;
  double offset_m_;
  double inverse_sigma_;
};

// A plane tie between the poses of two indices.
struct ResolvedPlaneTie {
  size_t from = 0;
  size_t to = 0;
  PlaneTie tie;
};

// A rotation prior resolved for one solve: the pose's index and the naming of the axes nearest
// its estimate (axes_from_cam = S * cam_from_axes^T).
struct ResolvedRotationPrior {
  size_t node = 0;
  Eigen::Matrix3d axes_from_cam;
  double sigma_rad = 0.0;
};
// The priors of one solve and the building's axes they share (estimated with the poses).
struct RotationPriors {
  std::vector<ResolvedRotationPrior> priors;
  std::vector<ResolvedPlaneTie> plane_ties;
  std::array<double, 4> world_from_axes = {0.0, 0.0, 0.0, 1.0};  // quaternion x, y, z, w
};

// S with S^T S = W for a symmetric positive semi-definite W (eigenvalues within rounding of zero
// count as zero), so that |S r|^2 = r^T W r.
Matrix6d SqrtInformation(const Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(information);
  const Vector6d root = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return root.asDiagonal() * eigen.eigenvectors().transpose();
}

// Quaternion (x, y, z, w) and position of one pose, as Ceres' parameter blocks.
struct PoseParameters {
  double q[4];
  double p[3];

  void Set(const Eigen::Isometry3d& world_from_cam) {
    Eigen::Map<Eigen::Quaterniond> rotation(q);
    Eigen::Map<Eigen::Vector3d> position(p);
    rotation = Eigen::Quaterniond(world_from_cam.linear()).normalized();
    position = world_from_cam.translation();
  }
  Eigen::Isometry3d Get() const {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = Eigen::Map<const Eigen::Quaterniond>(q).normalized().toRotationMatrix();
    pose.translation() = Eigen::Map<const Eigen::Vector3d>(p);
    return pose;
  }
};

double Chi2(const PoseGraphEdge& edge, const PoseParameters& from, const PoseParameters& to) {
  const Vector6d error = EdgeError(from.q, from.p, to.q, to.p,
                                   Eigen::Quaterniond(edge.to_in_from.linear()).normalized(),
                                   edge.to_in_from.translation());
  return error.dot(edge.information * error);
}

using Neighbours = std::unordered_map<int64_t, std::vector<std::pair<int64_t, size_t>>>;

// The poses within `hops` edges of `start`.
std::unordered_set<int64_t> PosesWithinHops(const Neighbours& neighbours,
                                            const std::vector<int64_t>& start, int hops) {
  std::unordered_set<int64_t> reached(start.begin(), start.end());
  std::vector<int64_t> frontier(reached.begin(), reached.end());
  for (int hop = 0; hop < hops && !frontier.empty(); ++hop) {
    std::vector<int64_t> next;
    for (int64_t pose : frontier) {
      const auto found = neighbours.find(pose);
      if (found == neighbours.end()) continue;
      for (const auto& [neighbour, edge] : found->second) {
        if (reached.insert(neighbour).second) next.push_back(neighbour);
      }
    }
    frontier = std::move(next);
  }
  return reached;
}

// Whether `a` reaches `b` through poses of `within` only, without edge `skipped`.
bool ConnectedWithout(const Neighbours& neighbours, const std::unordered_set<int64_t>& within,
                      int64_t a, int64_t b, size_t skipped) {
  std::unordered_set<int64_t> seen{a};
  std::vector<int64_t> stack{a};
  while (!stack.empty()) {
    const int64_t pose = stack.back();
    stack.pop_back();
    if (pose == b) return true;
    const auto found = neighbours.find(pose);
    if (found == neighbours.end()) continue;
    for (const auto& [neighbour, edge] : found->second) {
      if (edge != skipped && within.count(neighbour) > 0 && seen.insert(neighbour).second) {
        stack.push_back(neighbour);
      }
    }
  }
  return false;
}

ceres::LinearSolverType SparseSolver() {
  for (const auto library :
       {ceres::SUITE_SPARSE, ceres::EIGEN_SPARSE, ceres::ACCELERATE_SPARSE, ceres::CX_SPARSE}) {
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(library)) {
      return ceres::SPARSE_NORMAL_CHOLESKY;
    }
  }
  return ceres::CGNR;  // no sparse factorisation compiled in: iterative, still sparse
}

ceres::Solver::Options SolverOptions(const PoseGraphOptions& options) {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = SparseSolver();
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.max_solver_time_in_seconds = options.max_solver_time_s;
  solver_options.num_threads = options.num_threads;
  solver_options.logging_type = ceres::SILENT;
  solver_options.function_tolerance = options.function_tolerance;
  // Tighter than Ceres' defaults (1e-10, 1e-8), so that the cost decides when to stop.
  solver_options.gradient_tolerance = 1e-12;
  solver_options.parameter_tolerance = 1e-10;
  return solver_options;
}

// One least-squares solve of the `solved` edges, from the poses `initial`.
struct Solve {
  bool anything = false;  // some edge was solved
  ceres::Solver::Summary summary;
  std::vector<PoseParameters> parameters;  // the solution; `initial` for poses that did not move
  std::vector<bool> moved;                 // the poses the solve was free to move
  std::optional<std::array<double, 4>> world_from_axes;  // when the solve moved the axes
};

Solve SolveEdges(const std::vector<PoseGraphEdge>& edges, const internal::EdgeEnds& ends,
                 const std::vector<bool>& solved, const std::vector<Matrix6d>& sqrt_information,
                 const std::vector<PoseParameters>& initial, const std::vector<bool>& pinned,
                 const RotationPriors& rotation_priors, const PoseGraphOptions& options) {
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::CauchyLoss loop_loss(options.loop_loss_scale);
  ceres::CauchyLoss rotation_prior_loss(options.rotation_prior_loss_scale);
  const std::unique_ptr<ceres::LossFunction> odometry_loss(
      options.odometry_loss_scale > 0.0 ? new ceres::CauchyLoss(options.odometry_loss_scale)
                                        : nullptr);
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);

  Solve solve;
  solve.parameters = initial;
  solve.moved.assign(initial.size(), false);
  std::vector<bool> in_problem(initial.size(), false);
  std::vector<bool> ties(edges.size(), false);
  for (size_t e = 0; e < edges.size(); ++e) {
    if (!solved[e]) continue;
    const auto [a, b] = ends[e];
    problem.AddResidualBlock(EdgeCost::Create(edges[e].to_in_from, sqrt_information[e]),
                             IsLoopEdge(edges[e].type) ? &loop_loss : odometry_loss.get(),
                             solve.parameters[a].q, solve.parameters[a].p, solve.parameters[b].q,
                             solve.parameters[b].p);
    in_problem[a] = in_problem[b] = true;
    ties[e] = !edges[e].information.isZero();
  }
  if (problem.NumResidualBlocks() == 0) return solve;
  solve.anything = true;

  const std::vector<bool> held = internal::HeldPoses(ends, solved, ties, pinned);
  // A copy per solve: a solve that switches a loop off starts again from the same axes.
  std::array<double, 4> world_from_axes = rotation_priors.world_from_axes;
  bool axes_in_problem = false;
  for (const ResolvedRotationPrior& prior : rotation_priors.priors) {
    if (!in_problem[prior.node]) continue;  // a held pose's prior holds the axes
    problem.AddResidualBlock(RotationPriorCost::Create(prior.axes_from_cam, prior.sigma_rad),
                             &rotation_prior_loss, solve.parameters[prior.node].q,
                             world_from_axes.data());
    axes_in_problem = true;
  }
  if (axes_in_problem) problem.SetManifold(world_from_axes.data(), &quaternion_manifold);
  ceres::CauchyLoss plane_tie_loss(1.0);
  for (const ResolvedPlaneTie& tie : rotation_priors.plane_ties) {
    if (!in_problem[tie.from] || !in_problem[tie.to]) continue;
    problem.AddResidualBlock(PlaneTieCost::Create(tie.tie), &plane_tie_loss,
                             solve.parameters[tie.from].q, solve.parameters[tie.from].p,
                             solve.parameters[tie.to].p);
  }
  for (size_t i = 0; i < initial.size(); ++i) {
    if (!in_problem[i]) continue;
    problem.SetManifold(solve.parameters[i].q, &quaternion_manifold);
    if (held[i]) {
      problem.SetParameterBlockConstant(solve.parameters[i].q);
      problem.SetParameterBlockConstant(solve.parameters[i].p);
    }
    solve.moved[i] = !held[i];
  }
  ceres::Solve(SolverOptions(options), &problem, &solve.summary);
  if (axes_in_problem) solve.world_from_axes = world_from_axes;
  return solve;
}

// Solves, switches off the worst inconsistent loop edge (internal::WorstLoop), and solves again
// until none is. Each solve starts from the poses `initial`, so the answer after switching an edge
// off does not depend on where that edge had pulled the poses. Switches the edges off in `active`,
// fills the summary's solve figures and rejected edges; returns the last solve (nothing moved when
// it was not usable).
Solve SolveSwitchingOffLoops(const std::vector<PoseGraphEdge>& edges,
                             const internal::EdgeEnds& ends, const std::vector<bool>& selected,
                             const std::vector<Matrix6d>& sqrt_information,
                             const std::vector<PoseParameters>& initial,
                             const std::vector<bool>& pinned, const RotationPriors& rotation_priors,
                             const PoseGraphOptions& options, std::vector<bool>* active,
                             PoseGraphSummary* summary) {
  while (true) {
    std::vector<bool> solved(edges.size());
    for (size_t e = 0; e < edges.size(); ++e) solved[e] = (*active)[e] && selected[e];
    Solve solve = SolveEdges(edges, ends, solved, sqrt_information, initial, pinned,
                             rotation_priors, options);
    if (!solve.anything) {
      summary->converged = true;  // nothing to move
      return solve;
    }
    if (summary->solves == 0) summary->initial_cost = solve.summary.initial_cost;
    ++summary->solves;
    summary->iterations += static_cast<int>(solve.summary.iterations.size());
    summary->final_cost = solve.summary.final_cost;
    summary->converged = solve.summary.termination_type == ceres::CONVERGENCE;
    if (!solve.summary.IsSolutionUsable()) {
      summary->usable = false;
      solve.moved.assign(initial.size(), false);
      solve.parameters = initial;
      return solve;
    }
    std::vector<std::optional<double>> loop_chi2(edges.size());
    for (size_t e = 0; e < edges.size(); ++e) {
      if (solved[e] && IsLoopEdge(edges[e].type)) {
        loop_chi2[e] =
            Chi2(edges[e], solve.parameters[ends[e].first], solve.parameters[ends[e].second]);
      }
    }
    const std::optional<size_t> worst = internal::WorstLoop(loop_chi2, options.max_loop_chi2);
    if (!worst) return solve;
    (*active)[*worst] = false;
    summary->rejected_edges.push_back(*worst);
  }
}

// A rotation prior by pose index, for the stages below.
struct IndexedRotationPrior {
  size_t node = 0;
  RotationPrior prior;
};

double CauchyLoss(double chi2, double scale) {
  if (scale <= 0.0) return chi2;
  const double b = scale * scale;
  return b * std::log1p(chi2 / b);
}

// How badly poses `at` fit the measurements: every edge of `considered` with the solve's loss, and
// every prior of a pose in play at its nearest naming whether within its bound or not, with the
// priors' loss. Solutions that switched different loops off or named different priors are
// compared on the same terms.
double Misfit(const std::vector<PoseGraphEdge>& edges, const internal::EdgeEnds& ends,
              const std::vector<bool>& considered, const std::vector<PoseParameters>& at,
              const std::vector<IndexedRotationPrior>& priors,
              const Eigen::Matrix3d& world_from_axes, const PoseGraphOptions& options) {
  double misfit = 0.0;
  std::vector<bool> in_play(at.size(), false);
  for (size_t e = 0; e < edges.size(); ++e) {
    if (!considered[e]) continue;
    const auto [a, b] = ends[e];
    in_play[a] = in_play[b] = true;
    const double chi2 = Chi2(edges[e], at[a], at[b]);
    misfit += CauchyLoss(
        chi2, IsLoopEdge(edges[e].type) ? options.loop_loss_scale : options.odometry_loss_scale);
  }
  for (const IndexedRotationPrior& indexed : priors) {
    if (!in_play[indexed.node]) continue;
    const double deviation = NearestManhattanRotation(world_from_axes, indexed.prior.cam_from_axes,
                                                      at[indexed.node].Get().linear())
                                 .second;
    const double whitened = deviation / indexed.prior.sigma_rad;
    misfit += CauchyLoss(whitened * whitened, options.rotation_prior_loss_scale);
  }
  return 0.5 * misfit;
}

// The building's axes most priors agree on at poses `at`: of the axes each of up to 64 priors of
// poses in play (spread over the list) gives, the one the most priors lie within `tolerance_rad`
// of, up to naming. nullopt without priors in play.
std::optional<Eigen::Matrix3d> ConsensusAxes(const std::vector<IndexedRotationPrior>& priors,
                                             const std::vector<bool>& in_play,
                                             const std::vector<Eigen::Isometry3d>& at,
                                             double tolerance_rad) {
  std::vector<const IndexedRotationPrior*> candidates;
  for (const IndexedRotationPrior& indexed : priors) {
    if (in_play[indexed.node]) candidates.push_back(&indexed);
  }
  if (candidates.empty()) return std::nullopt;
  const size_t tries = std::min<size_t>(candidates.size(), 64);
  std::optional<Eigen::Matrix3d> best;
  int best_votes = -1;
  for (size_t k = 0; k < tries; ++k) {
    const IndexedRotationPrior& candidate = *candidates[k * candidates.size() / tries];
    const Eigen::Matrix3d axes = at[candidate.node].linear() * candidate.prior.cam_from_axes;
    int votes = 0;
    for (const IndexedRotationPrior* other : candidates) {
      if (NearestManhattanRotation(axes, other->prior.cam_from_axes, at[other->node].linear())
              .second <= tolerance_rad) {
        ++votes;
      }
    }
    if (votes > best_votes) {
      best_votes = votes;
      best = axes;
    }
  }
  return best;
}

// The `solved` edges as SeedPoses' measurements: the rotation weighted by the mean of its
// information's diagonal, the translation by its information (cross terms dropped).
std::vector<SeedEdge> SeedEdgesOf(const std::vector<PoseGraphEdge>& edges,
                                  const internal::EdgeEnds& ends, const std::vector<bool>& solved) {
  std::vector<SeedEdge> seed_edges;
  for (size_t e = 0; e < edges.size(); ++e) {
    if (!solved[e]) continue;
    SeedEdge seed;
    seed.from = ends[e].first;
    seed.to = ends[e].second;
    seed.to_in_from = edges[e].to_in_from;
    seed.rotation_weight = edges[e].information.bottomRightCorner<3, 3>().trace() / 3.0;
    seed.translation_information = edges[e].information.topLeftCorner<3, 3>();
    seed.bridging = edges[e].type == LinkType::kPrior;
    seed_edges.push_back(seed);
  }
  return seed_edges;
}

// The priors named from the poses `at` and the axes: each the naming nearest its pose's estimate,
// those within their bound.
std::vector<ResolvedRotationPrior> NamePriors(const std::vector<IndexedRotationPrior>& priors,
                                              const std::vector<PoseParameters>& at,
                                              const Eigen::Matrix3d& world_from_axes) {
  std::vector<ResolvedRotationPrior> named;
  for (const IndexedRotationPrior& indexed : priors) {
    const auto [measured, deviation] = NearestManhattanRotation(
        world_from_axes, indexed.prior.cam_from_axes, at[indexed.node].Get().linear());
    if (deviation <= indexed.prior.max_deviation_rad) {
      named.push_back(
          {indexed.node, world_from_axes.transpose() * measured, indexed.prior.sigma_rad});
    }
  }
  return named;
}

// Poses seeded (SeedPoses) with the building's axes one more unknown, each prior of a pose in
// play an edge from its pose to the axes, named nearest the poses `at` and the axes `axes` when
// within `max_deviation_rad` of it, well beyond the solves' bound: a part the links left turned
// by up to that much is turned to its axes. Returns the poses and the axes.
std::pair<std::vector<Eigen::Isometry3d>, Eigen::Matrix3d> SeedWithAxes(
    const std::vector<Eigen::Isometry3d>& estimates, const std::vector<bool>& held,
    std::vector<SeedEdge> seed_edges, const std::vector<IndexedRotationPrior>& priors,
    const std::vector<bool>& in_play, const std::vector<PoseParameters>& at,
    const Eigen::Matrix3d& axes, double max_deviation_rad) {
  const size_t axes_index = estimates.size();
  std::vector<Eigen::Isometry3d> with_axes = estimates;
  with_axes.push_back(Eigen::Isometry3d::Identity());
  with_axes.back().linear() = axes;
  std::vector<bool> held_with_axes = held;
  held_with_axes.push_back(false);
  for (const IndexedRotationPrior& indexed : priors) {
    if (!in_play[indexed.node]) continue;
    const auto [measured, deviation] = NearestManhattanRotation(axes, indexed.prior.cam_from_axes,
                                                                at[indexed.node].Get().linear());
    if (deviation > max_deviation_rad) continue;
    SeedEdge edge;
    edge.from = indexed.node;
    edge.to = axes_index;
    edge.to_in_from.linear() = measured.transpose() * axes;  // world_from_cam * it = the axes
    edge.rotation_weight = 1.0 / (indexed.prior.sigma_rad * indexed.prior.sigma_rad);
    seed_edges.push_back(edge);
  }
  std::vector<Eigen::Isometry3d> seeded = SeedPoses(with_axes, held_with_axes, seed_edges);
  const Eigen::Matrix3d seeded_axes = seeded.back().linear();
  seeded.pop_back();
  return {seeded, seeded_axes};
}

// A part's solve started from the poses `seed` (by index) and the axes `axes`, the priors named
// there; `active` is where its edges start, switched off as the solve finds them inconsistent.
struct SeededSolve {
  Solve solve;
  PoseGraphSummary summary;
  std::vector<bool> active;
};
SeededSolve SolveFrom(const std::vector<Eigen::Isometry3d>& seed, const Eigen::Matrix3d& axes,
                      const std::vector<PoseGraphEdge>& edges, const internal::EdgeEnds& ends,
                      const std::vector<bool>& selected,
                      const std::vector<Matrix6d>& sqrt_information,
                      const std::vector<bool>& pinned,
                      const std::vector<IndexedRotationPrior>& priors,
                      const PoseGraphOptions& options, std::vector<bool> active) {
  std::vector<PoseParameters> seeded(seed.size());
  for (size_t i = 0; i < seed.size(); ++i) seeded[i].Set(seed[i]);
  RotationPriors seeded_priors;
  Eigen::Map<Eigen::Quaterniond>(seeded_priors.world_from_axes.data()) =
      Eigen::Quaterniond(axes).normalized();
  seeded_priors.priors = NamePriors(priors, seeded, axes);
  PoseGraphOptions seeded_options = options;
  seeded_options.max_iterations = options.seeded_max_iterations;
  seeded_options.max_solver_time_s = options.seeded_max_solver_time_s;
  SeededSolve result;
  result.active = std::move(active);
  result.summary.edge_chi2.assign(edges.size(), 0.0);
  result.solve =
      SolveSwitchingOffLoops(edges, ends, selected, sqrt_information, seeded, pinned, seeded_priors,
                             seeded_options, &result.active, &result.summary);
  result.summary.seeded = true;
  return result;
}

// The axes a solve ended with (`fallback` when it did not move them).
Eigen::Matrix3d AxesOf(const Solve& solve, const Eigen::Matrix3d& fallback) {
  return solve.world_from_axes
             ? Eigen::Quaterniond(solve.world_from_axes->data()).normalized().toRotationMatrix()
             : fallback;
}

// OptimizeAroundSeeded's part: the same part solved from a seed its edges alone give, and from
// one that turns each part of it to the axes as named at the better of the two solutions so far;
// `solve`, `summary` and `active` become the one that fits every edge the part had before
// (`active_before`) and every prior best, if not already theirs.
void SolveFromSeedsIfBetter(const std::vector<PoseGraphEdge>& edges, const internal::EdgeEnds& ends,
                            const std::vector<bool>& selected,
                            const std::vector<Matrix6d>& sqrt_information,
                            const std::vector<PoseParameters>& initial,
                            const std::vector<bool>& pinned,
                            const std::vector<IndexedRotationPrior>& priors,
                            const Eigen::Matrix3d& world_from_axes, const PoseGraphOptions& options,
                            const std::vector<bool>& active_before, Solve* solve,
                            PoseGraphSummary* summary, std::vector<bool>* active) {
  // What both seeds are made of: the edges the solve kept, the poses holding the gauge.
  std::vector<bool> solved(edges.size()), considered(edges.size()), ties(edges.size());
  std::vector<bool> in_play(initial.size(), false);
  for (size_t e = 0; e < edges.size(); ++e) {
    solved[e] = (*active)[e] && selected[e];
    considered[e] = selected[e] && active_before[e];
    ties[e] = solved[e] && !edges[e].information.isZero();
    if (solved[e]) in_play[ends[e].first] = in_play[ends[e].second] = true;
  }
  std::vector<Eigen::Isometry3d> estimates(initial.size());
  for (size_t i = 0; i < initial.size(); ++i) estimates[i] = initial[i].Get();
  const std::vector<bool> held = internal::HeldPoses(ends, solved, ties, pinned);
  const std::vector<SeedEdge> seed_edges = SeedEdgesOf(edges, ends, solved);

  const auto misfit = [&](const Solve& of) {
    return Misfit(edges, ends, considered, of.parameters, priors, AxesOf(of, world_from_axes),
                  options);
  };
  double best_misfit = misfit(*solve);
  const auto solve_and_keep_if_better = [&](const std::vector<Eigen::Isometry3d>& seed,
                                            const Eigen::Matrix3d& axes) {
    SeededSolve seeded = SolveFrom(seed, axes, edges, ends, selected, sqrt_information, pinned,
                                   priors, options, active_before);
    if (!seeded.summary.usable) return false;
    const double seeded_misfit = misfit(seeded.solve);
    if (seeded_misfit >= best_misfit) return false;
    best_misfit = seeded_misfit;
    *solve = std::move(seeded.solve);
    *summary = std::move(seeded.summary);
    *active = std::move(seeded.active);
    return true;
  };
  const std::vector<Eigen::Isometry3d> from_edges = SeedPoses(estimates, held, seed_edges);
  solve_and_keep_if_better(
      from_edges,
      ConsensusAxes(priors, in_play, from_edges, DegToRad(2.0)).value_or(world_from_axes));
  if (priors.empty()) return;
  const auto [from_axes, axes] = SeedWithAxes(estimates, held, seed_edges, priors, in_play,
                                              solve->parameters, AxesOf(*solve, world_from_axes),
                                              DegToRad(options.seeded_max_axes_deviation_deg));
  solve_and_keep_if_better(from_axes, axes);
  // Parts the best solution so far still leaves a quarter turn from what their bridging links
  // say; a part turned right can bring its neighbours within reach of their naming, hence rounds.
  // (A bound of 45 degrees or more would let a turn and no turn both fit a bridge.)
  const int rounds =
      options.seeded_max_axes_deviation_deg < 45.0 ? options.seeded_max_turn_rounds : 0;
  for (int round = 0; round < rounds; ++round) {
    std::vector<Eigen::Isometry3d> best(initial.size());
    for (size_t i = 0; i < initial.size(); ++i) best[i] = solve->parameters[i].Get();
    int turned_parts = 0;
    const Eigen::Matrix3d best_axes = AxesOf(*solve, world_from_axes);
    const std::vector<Eigen::Isometry3d> turned =
        TurnPartsToTheirBridges(best, held, seed_edges, best_axes,
                                DegToRad(options.seeded_max_axes_deviation_deg), &turned_parts);
    if (turned_parts == 0 || !solve_and_keep_if_better(turned, best_axes)) break;
  }
}

}  // namespace

bool PoseGraphOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (max_iterations <= 0) return fail("max_iterations must be positive");
  if (!(max_solver_time_s > 0.0)) return fail("max_solver_time_s must be positive");
  if (num_threads <= 0) return fail("num_threads must be positive");
  if (!(function_tolerance > 0.0 && function_tolerance < 1.0)) {
    return fail("function_tolerance must be in (0, 1)");
  }
  if (!(odometry_loss_scale >= 0.0) || !std::isfinite(odometry_loss_scale)) {
    return fail("odometry_loss_scale must be finite and not negative (0: no robust loss)");
  }
  if (!(loop_loss_scale > 0.0) || !std::isfinite(loop_loss_scale)) {
    return fail("loop_loss_scale must be positive and finite");
  }
  // Infinity is allowed: it turns the rejection of loop edges off.
  if (!(max_loop_chi2 > 0.0)) return fail("max_loop_chi2 must be positive");
  if (!(rotation_prior_loss_scale > 0.0) || !std::isfinite(rotation_prior_loss_scale)) {
    return fail("rotation_prior_loss_scale must be positive and finite");
  }
  if (seeded_max_iterations <= 0) return fail("seeded_max_iterations must be positive");
  if (!(seeded_max_solver_time_s > 0.0)) return fail("seeded_max_solver_time_s must be positive");
  if (!(seeded_max_axes_deviation_deg >= 0.0 && seeded_max_axes_deviation_deg <= 180.0)) {
    return fail("seeded_max_axes_deviation_deg must be in [0, 180]");
  }
  if (seeded_max_turn_rounds < 0) return fail("seeded_max_turn_rounds must not be negative");
  return true;
}

void PoseGraph::AddPose(int64_t id, const Eigen::Isometry3d& world_from_cam) {
  SIGHTMAP_CHECK(IsRigid(world_from_cam), "pose " << id << " is not a finite rigid transform");
  const bool inserted = nodes_.emplace(id, Node{world_from_cam, false}).second;
  SIGHTMAP_CHECK(inserted, "pose " << id << " is already in the pose graph");
}

void PoseGraph::SetPose(int64_t id, const Eigen::Isometry3d& world_from_cam) {
  const auto node = nodes_.find(id);
  SIGHTMAP_CHECK(node != nodes_.end(), "pose " << id << " is not in the pose graph");
  SIGHTMAP_CHECK(IsRigid(world_from_cam), "pose " << id << " is not a finite rigid transform");
  node->second.world_from_cam = world_from_cam;
}

void PoseGraph::CheckMeasurement(const PoseGraphEdge& edge) const {
  SIGHTMAP_CHECK(IsRigid(edge.to_in_from), "edge " << edge.from << " -> " << edge.to
                                                   << " measures no finite rigid transform");
  const Matrix6d& information = edge.information;
  SIGHTMAP_CHECK(information.allFinite(),
                 "edge " << edge.from << " -> " << edge.to << " has a non-finite information");
  const double scale = std::max(1.0, information.cwiseAbs().maxCoeff());
  SIGHTMAP_CHECK((information - information.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale,
                 "edge " << edge.from << " -> " << edge.to << " has a non-symmetric information");
  const double smallest = Eigen::SelfAdjointEigenSolver<Matrix6d>(information).eigenvalues()(0);
  SIGHTMAP_CHECK(smallest >= -1e-9 * scale,
                 "edge " << edge.from << " -> " << edge.to
                         << " has an information that is not positive semi-definite (eigenvalue "
                         << smallest << ")");
}

size_t PoseGraph::AddEdge(const PoseGraphEdge& edge) {
  SIGHTMAP_CHECK(HasPose(edge.from) && HasPose(edge.to),
                 "edge " << edge.from << " -> " << edge.to << " joins an unknown pose");
  SIGHTMAP_CHECK(edge.from != edge.to,
                 "edge " << edge.from << " -> " << edge.to << " joins a pose to itself");
  CheckMeasurement(edge);
  edges_.push_back(edge);
  active_.push_back(true);
  return edges_.size() - 1;
}

void PoseGraph::SetEdgeMeasurement(size_t index, const Eigen::Isometry3d& to_in_from,
                                   const Matrix6d& information) {
  SIGHTMAP_CHECK(index < edges_.size(), "edge index " << index << " is out of range");
  PoseGraphEdge edge = edges_[index];
  edge.to_in_from = to_in_from;
  edge.information = information;
  CheckMeasurement(edge);
  edges_[index] = edge;
}

void PoseGraph::SetFixed(int64_t id, bool fixed) {
  const auto node = nodes_.find(id);
  SIGHTMAP_CHECK(node != nodes_.end(), "pose " << id << " is not in the pose graph");
  node->second.fixed = fixed;
}

bool PoseGraph::IsFixed(int64_t id) const {
  const auto node = nodes_.find(id);
  SIGHTMAP_CHECK(node != nodes_.end(), "pose " << id << " is not in the pose graph");
  return node->second.fixed;
}

void PoseGraph::SetEdgeActive(size_t index, bool active) {
  SIGHTMAP_CHECK(index < edges_.size(), "edge index " << index << " is out of range");
  active_[index] = active;
}

bool PoseGraph::EdgeActive(size_t index) const {
  SIGHTMAP_CHECK(index < edges_.size(), "edge index " << index << " is out of range");
  return active_[index];
}

Matrix6d DiagonalCovariance(double sigma_m, double sigma_rad) {
  Vector6d variances;
  variances.head<3>().setConstant(sigma_m * sigma_m);
  variances.tail<3>().setConstant(sigma_rad * sigma_rad);
  return variances.asDiagonal();
}

Matrix6d RidgedInverse(const Matrix6d& matrix, double ridge) {
  const Matrix6d inverse = (matrix + ridge * Matrix6d::Identity()).inverse();
  return 0.5 * (inverse + inverse.transpose());
}

Matrix6d FlooredInformation(const Matrix6d& information, double min_sigma_m, double min_sigma_rad) {
  constexpr double kRidge = 1e-9;  // a covariance of 1e9 along a direction the link does not fix
  return RidgedInverse(
      RidgedInverse(information, kRidge) + DiagonalCovariance(min_sigma_m, min_sigma_rad), 0.0);
}

std::optional<std::vector<size_t>> PoseGraph::FirmestPath(
    int64_t from, int64_t to, const std::function<Matrix6d(size_t edge)>& edge_covariance,
    double lever_m) const {
  SIGHTMAP_CHECK(HasPose(from) && HasPose(to),
                 "FirmestPath between unknown poses " << from << " and " << to);
  SIGHTMAP_CHECK(lever_m >= 0.0, "FirmestPath needs a lever >= 0, got " << lever_m);
  if (from == to) return std::vector<size_t>();
  std::unordered_map<int64_t, std::vector<size_t>> adjacent;
  for (size_t e = 0; e < edges_.size(); ++e) {
    if (!active_[e]) continue;
    adjacent[edges_[e].from].push_back(e);
    adjacent[edges_[e].to].push_back(e);
  }
  // Dijkstra on a scalar size of each edge's covariance; `via` is the edge a pose was reached by.
  std::unordered_map<size_t, double> steps;  // by edge index, computed once each
  std::unordered_map<int64_t, double> cost{{from, 0.0}};
  std::unordered_map<int64_t, size_t> via;
  using Entry = std::pair<double, int64_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
  open.emplace(0.0, from);
  while (!open.empty()) {
    const auto [reached_cost, id] = open.top();
    open.pop();
    if (reached_cost > cost[id]) continue;
    if (id == to) break;
    for (const size_t e : adjacent[id]) {
      const PoseGraphEdge& edge = edges_[e];
      const int64_t next = edge.from == id ? edge.to : edge.from;
      auto [it, inserted] = steps.try_emplace(e);
      if (inserted) {
        const Matrix6d covariance = edge_covariance(e);
        it->second = covariance.topLeftCorner<3, 3>().trace() +
                     lever_m * lever_m * covariance.bottomRightCorner<3, 3>().trace();
      }
      const double step = it->second;
      const auto known = cost.find(next);
      if (known != cost.end() && known->second <= reached_cost + step) continue;
      cost[next] = reached_cost + step;
      via[next] = e;
      open.emplace(reached_cost + step, next);
    }
  }
  if (!via.count(to)) return std::nullopt;
  std::vector<size_t> path;
  for (int64_t id = to; id != from;) {
    const PoseGraphEdge& edge = edges_[via.at(id)];
    path.push_back(via.at(id));
    id = edge.from == id ? edge.to : edge.from;
  }
  std::reverse(path.begin(), path.end());
  return path;
}

std::optional<Matrix6d> PoseGraph::PathCovariance(
    int64_t from, int64_t to, const std::function<Matrix6d(size_t edge)>& edge_covariance,
    double lever_m) const {
  const std::optional<std::vector<size_t>> path = FirmestPath(from, to, edge_covariance, lever_m);
  if (!path) return std::nullopt;
  return PathCovariance(from, *path, edge_covariance);
}

Matrix6d PoseGraph::PathCovariance(
    int64_t from, const std::vector<size_t>& path,
    const std::function<Matrix6d(size_t edge)>& edge_covariance) const {
  // Chained from `from` outwards: T_from_to = T_from_a T_a_b ...; an edge error r_ab in a's frame
  // reaches `from`'s frame through the adjoint of T_from_a (AdjointSe3).
  const Eigen::Isometry3d from_world = Pose(from).inverse();
  Matrix6d total = Matrix6d::Zero();
  for (const size_t e : path) {
    SIGHTMAP_CHECK(e < edges_.size(), "edge index " << e << " is out of range");
    const PoseGraphEdge& edge = edges_[e];
    // The edge's error lives in its `from` pose's frame, whichever way the path runs through it.
    const Matrix6d adjoint = AdjointSe3(from_world * Pose(edge.from));
    total += adjoint * edge_covariance(e) * adjoint.transpose();
  }
  return 0.5 * (total + total.transpose());
}

const RotationPrior* PoseGraph::RotationPriorOf(int64_t id) const {
  const auto prior = rotation_priors_.find(id);
  return prior == rotation_priors_.end() ? nullptr : &prior->second;
}

const Eigen::Isometry3d& PoseGraph::Pose(int64_t id) const {
  const auto node = nodes_.find(id);
  SIGHTMAP_CHECK(node != nodes_.end(), "pose " << id << " is not in the pose graph");
  return node->second.world_from_cam;
}

bool PoseGraph::HasPose(int64_t id) const { return nodes_.count(id) > 0; }

double PoseGraph::EdgeChi2(size_t index) const {
  SIGHTMAP_CHECK(index < edges_.size(), "edge index " << index << " is out of range");
  const PoseGraphEdge& edge = edges_[index];
  PoseParameters from, to;
  from.Set(Pose(edge.from));
  to.Set(Pose(edge.to));
  return Chi2(edge, from, to);
}

PoseGraphSummary PoseGraph::Optimize(const PoseGraphOptions& options) {
  return OptimizeEdges(options, Scope(), nullptr, nullptr);
}

PoseGraphSummary PoseGraph::OptimizeAround(int64_t id, const PoseGraphOptions& options) {
  SIGHTMAP_CHECK(nodes_.count(id) > 0, "pose " << id << " is not in the pose graph");
  Scope scope;
  scope.around = id;
  return OptimizeEdges(options, scope, nullptr, nullptr);
}

PoseGraphSummary PoseGraph::OptimizeAroundSeeded(int64_t id, const PoseGraphOptions& options) {
  SIGHTMAP_CHECK(nodes_.count(id) > 0, "pose " << id << " is not in the pose graph");
  Scope scope;
  scope.around = id;
  scope.seeded = true;
  return OptimizeEdges(options, scope, nullptr, nullptr);
}

PoseGraphSummary PoseGraph::OptimizeNear(size_t edge, int hops, double max_border_chi2_rise,
                                         const PoseGraphOptions& options) {
  SIGHTMAP_CHECK(edge < edges_.size(), "edge index " << edge << " is out of range");
  SIGHTMAP_CHECK(hops >= 0, "hops must be >= 0, not " << hops);
  SIGHTMAP_CHECK(max_border_chi2_rise >= 0.0, "max_border_chi2_rise must not be negative");
  const auto start = std::chrono::steady_clock::now();
  const int64_t from = edges_[edge].from;
  const int64_t to = edges_[edge].to;
  // Active edges by pose: (neighbour, edge index).
  Neighbours neighbours;
  for (size_t e = 0; e < edges_.size(); ++e) {
    if (!active_[e]) continue;
    neighbours[edges_[e].from].emplace_back(edges_[e].to, e);
    neighbours[edges_[e].to].emplace_back(edges_[e].from, e);
  }
  // Nothing is switched off in a window: an edge a window cannot satisfy may fit a larger one.
  PoseGraphOptions window_options = options;
  window_options.max_loop_chi2 = std::numeric_limits<double>::infinity();
  int iterations = 0;
  size_t reached = 0;
  for (int64_t window = hops; active_[edge] && window > 0 && window < (int64_t{1} << 30);
       window *= 4) {
    Scope scope;
    scope.around = to;
    scope.free = PosesWithinHops(neighbours, {from, to}, static_cast<int>(window));
    if (scope.free->size() == reached) break;  // the window stopped growing: it is the whole part
    reached = scope.free->size();
    // The new edge must close a cycle inside the window: then the window holds the path the edge
    // is checked against, and the correction is shared along it as the whole part would share it.
    // Without one (the first loop of a revisit) the correction belongs to a longer cycle.
    if (!ConnectedWithout(neighbours, *scope.free, from, to, edge)) continue;
    std::map<int64_t, Eigen::Isometry3d> before;
    std::vector<std::pair<size_t, double>> border;
    PoseGraphSummary summary = OptimizeEdges(window_options, scope, &before, &border);
    if (border.empty()) break;  // the window is the whole part: solved below, with switch-offs
    iterations += summary.iterations;
    if (WindowFits(summary, border, max_border_chi2_rise, options.max_loop_chi2)) {
      summary.local = true;
      summary.iterations = iterations;
      summary.time_s = SecondsSince(start);
      return summary;
    }
    for (const auto& [id, pose] : before) nodes_.at(id).world_from_cam = pose;
  }
  PoseGraphSummary summary = OptimizeAround(to, options);
  summary.iterations += iterations;
  summary.time_s = SecondsSince(start);
  return summary;
}

bool PoseGraph::WindowFits(const PoseGraphSummary& summary,
                           const std::vector<std::pair<size_t, double>>& border,
                           double max_border_chi2_rise, double max_loop_chi2) const {
  if (!summary.usable) return false;
  for (size_t e = 0; e < edges_.size(); ++e) {
    if (active_[e] && IsLoopEdge(edges_[e].type) && summary.edge_chi2[e] > max_loop_chi2) {
      return false;
    }
  }
  // The poses held at the border would move to share a correction meant for more than the window.
  for (const auto& [edge, chi2_before] : border) {
    if (summary.edge_chi2[edge] > chi2_before + max_border_chi2_rise) return false;
  }
  return true;
}

PoseGraphSummary PoseGraph::OptimizeEdges(const PoseGraphOptions& options, const Scope& scope,
                                          std::map<int64_t, Eigen::Isometry3d>* before,
                                          std::vector<std::pair<size_t, double>>* border) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  PoseGraphSummary summary;
  summary.edge_chi2.assign(edges_.size(), 0.0);

  // Poses by index (in id order) and edges as index pairs.
  std::vector<Node*> nodes;
  std::vector<int64_t> ids;
  std::map<int64_t, size_t> index_of;
  for (auto& [id, node] : nodes_) {
    index_of[id] = nodes.size();
    nodes.push_back(&node);
    ids.push_back(id);
  }
  internal::EdgeEnds ends(edges_.size());
  for (size_t e = 0; e < edges_.size(); ++e) {
    ends[e] = {index_of.at(edges_[e].from), index_of.at(edges_[e].to)};
  }
  // The poses that may move (all, or those of `free`) and the edges in play.
  std::vector<bool> free(nodes.size(), true);
  if (scope.free) {
    for (size_t i = 0; i < nodes.size(); ++i) free[i] = scope.free->count(ids[i]) > 0;
  }
  const std::vector<bool> selected = internal::SelectEdges(
      ends, active_, free,
      scope.around ? std::optional<size_t>(index_of.at(*scope.around)) : std::nullopt);
  std::vector<Matrix6d> sqrt_information(edges_.size());
  for (size_t e = 0; e < edges_.size(); ++e) {
    if (selected[e]) sqrt_information[e] = SqrtInformation(edges_[e].information);
  }
  std::vector<PoseParameters> initial(nodes.size());
  std::vector<bool> pinned(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    initial[i].Set(nodes[i]->world_from_cam);
    pinned[i] = nodes[i]->fixed || !free[i];
  }
  if (border) {
    for (size_t e = 0; e < edges_.size(); ++e) {
      if (selected[e] && free[ends[e].first] != free[ends[e].second]) {
        border->emplace_back(e, Chi2(edges_[e], initial[ends[e].first], initial[ends[e].second]));
      }
    }
    // A window without a border is its whole part: the caller solves that itself.
    if (border->empty()) return summary;
  }

  // Each prior's naming of the axes is the one nearest the pose's estimate at the start. Priors
  // take part only in solves of whole parts, where the axes move with the poses: in a window the
  // axes, placed by the first prior's pose, are held, and a pose placed by the motion model
  // before them leaves them turned against the loops that correct it (1 Hz walks: priors in
  // windows switched 50-100 correct loops off).
  RotationPriors rotation_priors;
  Eigen::Map<Eigen::Quaterniond>(rotation_priors.world_from_axes.data()) = world_from_axes_;
  const Eigen::Matrix3d world_from_axes = world_from_axes_.toRotationMatrix();
  std::vector<IndexedRotationPrior> indexed_priors;
  for (const auto& [id, prior] : rotation_priors_) {
    indexed_priors.push_back({index_of.at(id), prior});
  }
  if (!scope.free) {
    rotation_priors.priors = NamePriors(indexed_priors, initial, world_from_axes);
    for (const PlaneTie& tie : plane_ties_) {
      rotation_priors.plane_ties.push_back({index_of.at(tie.from), index_of.at(tie.to), tie});
    }
  }
  const std::vector<bool> active_before = active_;
  Solve solve = SolveSwitchingOffLoops(edges_, ends, selected, sqrt_information, initial, pinned,
                                       rotation_priors, options, &active_, &summary);
  if (options.retry_rejected_loops_without_priors && !rotation_priors.priors.empty() &&
      !summary.rejected_edges.empty()) {
    // The priors' namings were taken from poses a switched-off loop may say are wrong (a stretch
    // the tracker turned 180 degrees keeps a naming of the axes 180 degrees off, and the loop
    // that would turn it back is switched off). Solved first by the loops alone, the namings
    // from that solution: kept when fewer loops are switched off so.
    const std::vector<bool> active_with_priors = active_;
    active_ = active_before;
    PoseGraphSummary retry;
    retry.edge_chi2.assign(edges_.size(), 0.0);
    RotationPriors loops_alone;
    loops_alone.world_from_axes = rotation_priors.world_from_axes;
    const Solve first = SolveSwitchingOffLoops(edges_, ends, selected, sqrt_information, initial,
                                               pinned, loops_alone, options, &active_, &retry);
    RotationPriors renamed = loops_alone;
    renamed.priors = NamePriors(indexed_priors, first.parameters, world_from_axes);
    Solve second =
        SolveSwitchingOffLoops(edges_, ends, selected, sqrt_information, first.parameters, pinned,
                               renamed, options, &active_, &retry);
    if (retry.usable && retry.rejected_edges.size() < summary.rejected_edges.size()) {
      solve = std::move(second);
      summary = std::move(retry);
    } else {
      active_ = active_with_priors;
    }
  }
  if (scope.seeded && summary.usable && solve.anything) {
    SolveFromSeedsIfBetter(edges_, ends, selected, sqrt_information, initial, pinned,
                           indexed_priors, world_from_axes, options, active_before, &solve,
                           &summary, &active_);
  }
  if (solve.world_from_axes) {
    world_from_axes_ = Eigen::Map<const Eigen::Quaterniond>(solve.world_from_axes->data());
    world_from_axes_.normalize();
  }
  const std::vector<PoseParameters>& parameters = solve.parameters;
  const std::vector<bool>& moved = solve.moved;

  // Poses that did not take part keep their exact input (no round trip through a quaternion).
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!moved[i]) continue;
    if (before) before->emplace(ids[i], nodes[i]->world_from_cam);
    nodes[i]->world_from_cam = parameters[i].Get();
    summary.moved_poses.push_back(ids[i]);
  }
  for (size_t e = 0; e < edges_.size(); ++e) {
    if (active_[e]) {
      summary.edge_chi2[e] = Chi2(edges_[e], parameters[ends[e].first], parameters[ends[e].second]);
    }
  }
  summary.time_s = SecondsSince(start);
  return summary;
}

void PoseGraph::SetRotationPrior(int64_t id, const RotationPrior& prior) {
  SIGHTMAP_CHECK(HasPose(id), "a rotation prior for unknown pose " << id);
  SIGHTMAP_CHECK(IsRigid(Eigen::Isometry3d(prior.cam_from_axes)),
                 "a rotation prior's axes must be a rotation (pose " << id << ")");
  SIGHTMAP_CHECK(
      prior.sigma_rad > 0.0 && std::isfinite(prior.sigma_rad) && prior.max_deviation_rad >= 0.0,
      "a rotation prior needs a positive sigma and a non-negative deviation");
  // The first prior places the axes where its pose's estimate says they are.
  if (rotation_priors_.empty()) {
    world_from_axes_ = Eigen::Quaterniond(Pose(id).linear() * prior.cam_from_axes).normalized();
  }
  rotation_priors_[id] = prior;
}

void PoseGraph::SetPlaneTies(std::vector<PlaneTie> ties) {
  for (const PlaneTie& tie : ties) {
    if (!HasPose(tie.from) || !HasPose(tie.to)) {
      SIGHTMAP_THROW(InvalidArgument,
                     "a plane tie between unknown poses " << tie.from << " and " << tie.to);
    }
    if (!(tie.sigma_m > 0.0 && std::isfinite(tie.sigma_m) && std::isfinite(tie.offset_m) &&
          tie.normal_in_from.allFinite())) {
      SIGHTMAP_THROW(InvalidArgument, "a plane tie needs a positive sigma and finite figures");
    }
  }
  plane_ties_ = std::move(ties);
}

SIGHTMAP_OPTIONS_JSON(PoseGraphOptions, max_iterations, max_solver_time_s, num_threads,
                      function_tolerance, loop_loss_scale, odometry_loss_scale, max_loop_chi2,
                      rotation_prior_loss_scale, retry_rejected_loops_without_priors,
                      seeded_max_iterations, seeded_max_solver_time_s,
                      seeded_max_axes_deviation_deg, seeded_max_turn_rounds)

}  // namespace sightmap::slam
