#include "slam/pose_seed.h"

#include <algorithm>
#include <functional>
#include <map>
#include <optional>

#include <Eigen/SVD>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "core/check.h"
#include "core/rotation.h"
#include "slam/manhattan_frame.h"
#include "slam/pose_graph_stages.h"

namespace sightmap::slam {
namespace {

constexpr size_t kNone = static_cast<size_t>(-1);
// SeedPoses' default anchor: positions no edge fixes keep their estimate.
constexpr double kTranslationAnchorWeight = 1e-6;

// The normal equations of sum |A_from x_from + A_to x_to - c|^2_W over 3-vector unknowns, with
// `cols` right-hand sides solved at once (x and c are 3 x cols).
class BlockLeastSquares {
 public:
  BlockLeastSquares(size_t unknowns, int cols)
      : unknowns_(unknowns), rhs_(Eigen::MatrixXd::Zero(3 * unknowns, cols)) {}

  // `from`/`to` are unknowns' indices or kNone for a known value (given in known_*).
  void Add(size_t from, const Eigen::Matrix3d& a_from, const Eigen::MatrixXd& known_from, size_t to,
           const Eigen::Matrix3d& a_to, const Eigen::MatrixXd& known_to, Eigen::MatrixXd c,
           const Eigen::Matrix3d& weight) {
    if (from == kNone) c -= a_from * known_from;
    if (to == kNone) c -= a_to * known_to;
    const auto add_block = [&](size_t i, size_t j, const Eigen::Matrix3d& block) {
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
          if (block(r, k) != 0.0) triplets_.emplace_back(3 * i + r, 3 * j + k, block(r, k));
        }
      }
    };
    if (from != kNone) {
      add_block(from, from, a_from.transpose() * weight * a_from);
      rhs_.middleRows<3>(3 * from) += a_from.transpose() * weight * c;
    }
    if (to != kNone) {
      add_block(to, to, a_to.transpose() * weight * a_to);
      rhs_.middleRows<3>(3 * to) += a_to.transpose() * weight * c;
    }
    if (from != kNone && to != kNone) {
      const Eigen::Matrix3d cross = a_from.transpose() * weight * a_to;
      add_block(from, to, cross);
      add_block(to, from, cross.transpose());
    }
  }

  // Solves with each unknown also pulled to `anchor` (3 x cols each) with weight
  // `anchor_weight` times the system's mean diagonal. Empty when the factorisation fails.
  std::vector<Eigen::MatrixXd> Solve(const std::vector<Eigen::MatrixXd>& anchor,
                                     double anchor_weight) {
    Eigen::VectorXd diagonal = Eigen::VectorXd::Zero(3 * unknowns_);
    for (const auto& t : triplets_) {
      if (t.row() == t.col()) diagonal[t.row()] += t.value();
    }
    const double epsilon =
        anchor_weight * std::max(diagonal.size() > 0 ? diagonal.mean() : 0.0, 1.0);
    for (size_t i = 0; i < unknowns_; ++i) {
      for (int r = 0; r < 3; ++r) triplets_.emplace_back(3 * i + r, 3 * i + r, epsilon);
      rhs_.middleRows<3>(3 * i) += epsilon * anchor[i];
    }
    Eigen::SparseMatrix<double> normal(3 * unknowns_, 3 * unknowns_);
    normal.setFromTriplets(triplets_.begin(), triplets_.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
    if (solver.info() != Eigen::Success) return {};
    const Eigen::MatrixXd x = solver.solve(rhs_);
    if (solver.info() != Eigen::Success || !x.allFinite()) return {};
    std::vector<Eigen::MatrixXd> out(unknowns_);
    for (size_t i = 0; i < unknowns_; ++i) out[i] = x.middleRows<3>(3 * i);
    return out;
  }

 private:
  size_t unknowns_;
  std::vector<Eigen::Triplet<double>> triplets_;
  Eigen::MatrixXd rhs_;
};

Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& matrix) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(matrix, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

// The chordal relaxation's rotations of the poses `unknown` maps to unknowns (the rest held at
// `initial`); empty when the system cannot be solved.
std::vector<Eigen::Matrix3d> ChordalRotations(const std::vector<Eigen::Isometry3d>& initial,
                                              const std::vector<size_t>& unknown,
                                              const std::vector<size_t>& pose_of,
                                              const std::vector<SeedEdge>& edges,
                                              double anchor_weight) {
  // One row of R at a time as the three right-hand sides: R_to = R_from M reads
  // row_to = M^T row_from for each row (as column vectors), i.e. x = R^T column-wise.
  BlockLeastSquares rotations(pose_of.size(), 3);
  for (const SeedEdge& edge : edges) {
    if (edge.rotation_weight <= 0.0) continue;
    const Eigen::Matrix3d m = edge.to_in_from.linear();
    rotations.Add(unknown[edge.from], -m.transpose(), initial[edge.from].linear().transpose(),
                  unknown[edge.to], Eigen::Matrix3d::Identity(),
                  initial[edge.to].linear().transpose(), Eigen::MatrixXd::Zero(3, 3),
                  edge.rotation_weight * Eigen::Matrix3d::Identity());
  }
  std::vector<Eigen::MatrixXd> anchor(pose_of.size());
  for (size_t k = 0; k < pose_of.size(); ++k) anchor[k] = initial[pose_of[k]].linear().transpose();
  const std::vector<Eigen::MatrixXd> rows = rotations.Solve(anchor, anchor_weight);
  std::vector<Eigen::Matrix3d> out;
  if (rows.empty()) return out;
  out.reserve(pose_of.size());
  for (size_t k = 0; k < pose_of.size(); ++k) out.push_back(NearestRotation(rows[k].transpose()));
  return out;
}

// Positions with the rotations of `poses` held: R_from^T (t_to - t_from) = M.t. False when the
// system cannot be solved (the positions are then left as they are).
bool SolveTranslations(const std::vector<size_t>& unknown, const std::vector<size_t>& pose_of,
                       const std::vector<SeedEdge>& edges, double anchor_weight,
                       std::vector<Eigen::Isometry3d>* poses) {
  BlockLeastSquares translations(pose_of.size(), 1);
  for (const SeedEdge& edge : edges) {
    if (edge.translation_information.isZero()) continue;
    const Eigen::Matrix3d from_rotation_t = (*poses)[edge.from].linear().transpose();
    translations.Add(unknown[edge.from], -from_rotation_t, (*poses)[edge.from].translation(),
                     unknown[edge.to], from_rotation_t, (*poses)[edge.to].translation(),
                     edge.to_in_from.translation(), edge.translation_information);
  }
  std::vector<Eigen::MatrixXd> anchor(pose_of.size());
  for (size_t k = 0; k < pose_of.size(); ++k) anchor[k] = (*poses)[pose_of[k]].translation();
  const std::vector<Eigen::MatrixXd> positions = translations.Solve(anchor, anchor_weight);
  if (positions.empty()) return false;
  for (size_t k = 0; k < pose_of.size(); ++k) {
    (*poses)[pose_of[k]].translation() = positions[k].col(0);
  }
  return true;
}

// Unknown indices of the poses the edges touch that are not held (kNone for the rest).
std::vector<size_t> Unknowns(size_t poses, const std::vector<bool>& held,
                             const std::vector<SeedEdge>& edges, std::vector<size_t>* pose_of) {
  std::vector<size_t> unknown(poses, kNone);
  for (const SeedEdge& edge : edges) {
    SIGHTMAP_CHECK(edge.from < poses && edge.to < poses && edge.from != edge.to,
                   "a seed edge joins two different known poses");
    for (const size_t i : {edge.from, edge.to}) {
      if (!held[i] && unknown[i] == kNone) {
        unknown[i] = pose_of->size();
        pose_of->push_back(i);
      }
    }
  }
  return unknown;
}

// The rigid parts the edges other than bridging ones make, over the poses any edge touches.
struct Parts {
  std::vector<std::vector<size_t>> members;  // each part's poses, in index order
  std::vector<size_t> of;                    // each pose's part (kNone: no edge touches it)
  std::vector<size_t> by_size;               // parts, largest first (the first of equals first)
};

// The parts `joined` makes of the poses any edge touches.
Parts PartsOf(size_t poses, const std::vector<SeedEdge>& edges,
              const std::function<bool(const SeedEdge&)>& joined) {
  internal::Components components(poses);
  std::vector<bool> touched(poses, false);
  for (const SeedEdge& edge : edges) {
    touched[edge.from] = touched[edge.to] = true;
    if (joined(edge)) components.Join(edge.from, edge.to);
  }
  Parts parts;
  parts.of.assign(poses, kNone);
  std::map<size_t, size_t> part_of_root;
  for (size_t i = 0; i < poses; ++i) {
    if (!touched[i]) continue;
    const auto [it, inserted] = part_of_root.try_emplace(components.Find(i), parts.members.size());
    if (inserted) parts.members.emplace_back();
    parts.members[it->second].push_back(i);
    parts.of[i] = it->second;
  }
  parts.by_size.resize(parts.members.size());
  for (size_t k = 0; k < parts.by_size.size(); ++k) parts.by_size[k] = k;
  std::stable_sort(parts.by_size.begin(), parts.by_size.end(), [&](size_t a, size_t b) {
    return parts.members[a].size() > parts.members[b].size();
  });
  return parts;
}

}  // namespace

std::vector<Eigen::Isometry3d> SeedPoses(const std::vector<Eigen::Isometry3d>& initial,
                                         const std::vector<bool>& held,
                                         const std::vector<SeedEdge>& edges, double anchor_weight) {
  SIGHTMAP_CHECK(held.size() == initial.size(), "one held flag a pose");
  SIGHTMAP_CHECK(anchor_weight > 0.0, "the anchor weight must be positive");
  std::vector<size_t> pose_of;
  const std::vector<size_t> unknown = Unknowns(initial.size(), held, edges, &pose_of);
  std::vector<Eigen::Isometry3d> seeded = initial;
  if (pose_of.empty()) return seeded;
  const std::vector<Eigen::Matrix3d> rotations =
      ChordalRotations(initial, unknown, pose_of, edges, anchor_weight);
  if (rotations.empty()) return seeded;
  for (size_t k = 0; k < pose_of.size(); ++k) seeded[pose_of[k]].linear() = rotations[k];
  SolveTranslations(unknown, pose_of, edges, anchor_weight, &seeded);
  return seeded;
}

std::vector<Eigen::Isometry3d> TurnPartsToTheirBridges(const std::vector<Eigen::Isometry3d>& poses,
                                                       const std::vector<bool>& held,
                                                       const std::vector<SeedEdge>& edges,
                                                       const Eigen::Matrix3d& world_from_axes,
                                                       double max_deviation_rad,
                                                       int* turned_parts) {
  SIGHTMAP_CHECK(held.size() == poses.size(), "one held flag a pose");
  SIGHTMAP_CHECK(max_deviation_rad >= 0.0 && max_deviation_rad < kPi / 4.0,
                 "max_deviation_rad must be in [0, pi/4), got " << max_deviation_rad);
  if (turned_parts != nullptr) *turned_parts = 0;
  std::vector<size_t> pose_of;
  const std::vector<size_t> unknown = Unknowns(poses.size(), held, edges, &pose_of);
  std::vector<Eigen::Isometry3d> turned = poses;
  std::vector<Eigen::Matrix3d> turns;
  size_t identity = 0;
  for (const Eigen::Matrix3d& symmetry : ManhattanSymmetries()) {
    if (symmetry.isIdentity()) identity = turns.size();
    turns.push_back(world_from_axes * symmetry * world_from_axes.transpose());
  }
  // The turn a bridge says its `inside` end's part needs, given the other end's part's turn.
  const auto vote = [&](const SeedEdge& bridge, bool to_inside,
                        const Eigen::Matrix3d& outside_turn) -> std::optional<size_t> {
    const size_t inside = to_inside ? bridge.to : bridge.from;
    const size_t outside = to_inside ? bridge.from : bridge.to;
    const Eigen::Matrix3d inside_in_outside =
        to_inside ? Eigen::Matrix3d(bridge.to_in_from.linear())
                  : Eigen::Matrix3d(bridge.to_in_from.linear().transpose());
    const Eigen::Matrix3d needed = outside_turn * poses[outside].linear() * inside_in_outside *
                                   poses[inside].linear().transpose();
    for (size_t t = 0; t < turns.size(); ++t) {
      if (Eigen::AngleAxisd(needed * turns[t].transpose()).angle() <= max_deviation_rad) return t;
    }
    return std::nullopt;
  };
  // Rigid parts, and those joined by a bridge that agrees with them as they are taken as one:
  // a part that sits a quarter turn off drags the small parts bridged to it along, and they
  // would outvote its one bridge to the rest.
  const Parts parts = PartsOf(poses.size(), edges, [&](const SeedEdge& edge) {
    return !edge.bridging || vote(edge, true, Eigen::Matrix3d::Identity()) == identity;
  });
  if (parts.members.size() < 2) return turned;
  // From the largest part outwards: of the parts bridged to those already placed, the largest
  // next, taking the turn most of its bridges to placed parts ask for (no turn on a tie). Votes
  // of parts not yet placed would let a small part a quarter turn off turn a larger one its way
  // (and starting from a small part, as the one holding the map's first pose, does the same).
  std::vector<size_t> label(parts.members.size(), identity);
  std::vector<bool> placed(parts.members.size(), false);
  placed[parts.by_size.front()] = true;
  for (;;) {
    size_t next = kNone;
    for (const size_t part : parts.by_size) {
      if (placed[part]) continue;
      const bool bridged = std::any_of(edges.begin(), edges.end(), [&](const SeedEdge& edge) {
        const size_t a = parts.of[edge.from], b = parts.of[edge.to];
        return edge.bridging && ((a == part && placed[b]) || (b == part && placed[a]));
      });
      if (bridged) {
        next = part;
        break;
      }
    }
    if (next == kNone) break;
    std::vector<int> votes(turns.size(), 0);
    for (const SeedEdge& edge : edges) {
      const size_t from_part = parts.of[edge.from], to_part = parts.of[edge.to];
      if (!edge.bridging || (from_part != next && to_part != next)) continue;
      const bool to_inside = to_part == next;
      const size_t other = to_inside ? from_part : to_part;
      if (other == next || !placed[other]) continue;
      if (const std::optional<size_t> t = vote(edge, to_inside, turns[label[other]])) ++votes[*t];
    }
    for (size_t t = 0; t < turns.size(); ++t) {
      if (votes[t] > votes[label[next]]) label[next] = t;
    }
    placed[next] = true;
  }
  // The part holding the first held pose keeps the map's frame: when it is to turn, everything
  // turns back by as much instead (the turns are a group, so each stays one of them).
  const auto first_held = std::find(held.begin(), held.end(), true);
  if (first_held != held.end()) {
    const size_t held_part = parts.of[static_cast<size_t>(first_held - held.begin())];
    if (held_part != kNone && label[held_part] != identity) {
      const Eigen::Matrix3d back = turns[label[held_part]].transpose();
      for (size_t& part_label : label) {
        const Eigen::Matrix3d turn = back * turns[part_label];
        for (size_t t = 0; t < turns.size(); ++t) {
          if (turns[t].isApprox(turn, 1e-6)) part_label = t;
        }
      }
    }
  }
  // Each turned part turns about its first pose; then every position is solved again with the
  // rotations held, so that the bridges place the turned parts.
  int turned_count = 0;
  for (size_t part = 0; part < parts.members.size(); ++part) {
    if (label[part] == identity) continue;
    ++turned_count;
    const Eigen::Matrix3d& turn = turns[label[part]];
    const Eigen::Vector3d pivot = poses[parts.members[part].front()].translation();
    for (const size_t i : parts.members[part]) {
      turned[i].linear() = turn * poses[i].linear();
      turned[i].translation() = pivot + turn * (poses[i].translation() - pivot);
    }
  }
  if (turned_parts != nullptr) *turned_parts = turned_count;
  if (turned_count > 0 && !pose_of.empty()) {
    SolveTranslations(unknown, pose_of, edges, kTranslationAnchorWeight, &turned);
  }
  return turned;
}

}  // namespace sightmap::slam
