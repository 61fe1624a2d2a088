// SPDX-License-Identifier: Apache-2.0
#include "algo/stereo_refinement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <opencv2/calib3d.hpp>

#include "algo/map_sampling.hpp"

namespace cylscan::algo {
namespace {

// The global unknowns: main intrinsics, aux intrinsics, R (Rodrigues), T.
constexpr int kIntrinsics = 9;  // fx fy cx cy k1 k2 p1 p2 k3
constexpr int kMainOffset = 0;
constexpr int kAuxOffset = 9;
constexpr int kRotationOffset = 18;
constexpr int kTranslationOffset = 21;
constexpr int kGlobals = 24;
constexpr int kBoardUnknowns = 6;  // Rodrigues + translation, main frame
constexpr int kPlaneUnknowns = 3;  // q = n / d: points X with q·X = 1

// Central-difference steps, chosen so that each moves an image point by about
// 1e-3 px (well inside a pixel, where the bilinear phase is linear) and stays
// far above double rounding.
constexpr std::array<double, kIntrinsics> kIntrinsicSteps = {1e-2, 1e-2, 1e-2, 1e-2, 1e-5,
                                                             1e-5, 1e-6, 1e-6, 1e-5};
constexpr double kRotationStep = 1e-6;
constexpr double kTranslationStep = 1e-3;
constexpr double kPlaneStep = 1e-9;
// The fixed-point undistortion contracts by about k1·r² per step (< 1e-2 for
// the narrow lenses of a scanning head): a dozen steps reach double precision.
constexpr int kUndistortIterations = 12;

using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;

std::array<bool, kIntrinsics> freeIntrinsics(const std::string& model) {
  //                  fx    fy    cx    cy    k1    k2    p1     p2     k3
  if (model == "k1k2") return {true, true, true, true, true, true, false, false, false};
  if (model == "k1k2p1p2") return {true, true, true, true, true, true, true, true, false};
  if (model == "k1k2p1p2k3") return {true, true, true, true, true, true, true, true, true};
  throw std::invalid_argument("stereo refinement: unknown distortion model '" + model + "'");
}

void putCamera(const PinholeCamera& camera, Vector& x, int offset) {
  const cv::Matx33d& k = camera.camera_matrix;
  x[offset + 0] = k(0, 0);
  x[offset + 1] = k(1, 1);
  x[offset + 2] = k(0, 2);
  x[offset + 3] = k(1, 2);
  for (int i = 0; i < 5; ++i)
    x[offset + 4 + i] = camera.dist_coeffs[i];
}

struct CameraParams {
  cv::Matx33d k;
  cv::Vec<double, 5> dist;
};

CameraParams cameraAt(const Vector& x, int offset) {
  CameraParams c;
  c.k = cv::Matx33d(x[offset], 0, x[offset + 2], 0, x[offset + 1], x[offset + 3], 0, 0, 1);
  for (int i = 0; i < 5; ++i)
    c.dist[i] = x[offset + 4 + i];
  return c;
}

cv::Vec3d vec3At(const Vector& x, int offset) {
  return {x[offset], x[offset + 1], x[offset + 2]};
}

// A block of residuals that depends on the globals and on one local block of
// unknowns (a board pose or a plane).
class ResidualGroup {
 public:
  virtual ~ResidualGroup() = default;
  virtual int localOffset() const = 0;
  virtual int localSize() const = 0;
  virtual double localStep(int i) const = 0;
  // Weighted residuals at x.
  virtual void evaluate(const Vector& x, std::vector<double>& r) = 0;
};

class BoardGroup final : public ResidualGroup {
 public:
  BoardGroup(const CheckerboardObservations& boards, std::size_t view, int offset)
      : object_(boards.object.begin(), boards.object.end()),
        view_(boards.views[view]),
        offset_(offset) {}

  int localOffset() const override { return offset_; }
  int localSize() const override { return kBoardUnknowns; }
  double localStep(int i) const override { return i < 3 ? kRotationStep : kTranslationStep; }

  void setSigma(double sigma_px) { weight_ = 1.0 / sigma_px; }

  // Unweighted pixel residuals: main (x, y) per corner, then aux.
  void pixelResiduals(const Vector& x, std::vector<double>& r) const {
    const CameraParams main = cameraAt(x, kMainOffset);
    const CameraParams aux = cameraAt(x, kAuxOffset);
    const cv::Vec3d rvec = vec3At(x, offset_);
    const cv::Vec3d tvec = vec3At(x, offset_ + 3);
    cv::Matx33d rb, r_pair;
    cv::Rodrigues(rvec, rb);
    cv::Rodrigues(vec3At(x, kRotationOffset), r_pair);
    const cv::Matx33d r_aux = r_pair * rb;
    const cv::Vec3d t_aux = r_pair * tvec + vec3At(x, kTranslationOffset);
    cv::Vec3d rvec_aux;
    cv::Rodrigues(r_aux, rvec_aux);
    cv::projectPoints(object_, rvec, tvec, main.k, main.dist, projected_main_);
    cv::projectPoints(object_, rvec_aux, t_aux, aux.k, aux.dist, projected_aux_);
    r.resize(4 * object_.size());
    std::size_t i = 0;
    for (std::size_t c = 0; c < object_.size(); ++c) {
      r[i++] = projected_main_[c].x - view_.main[c].x;
      r[i++] = projected_main_[c].y - view_.main[c].y;
    }
    for (std::size_t c = 0; c < object_.size(); ++c) {
      r[i++] = projected_aux_[c].x - view_.aux[c].x;
      r[i++] = projected_aux_[c].y - view_.aux[c].y;
    }
  }

  void evaluate(const Vector& x, std::vector<double>& r) override {
    pixelResiduals(x, r);
    for (double& v : r)
      v *= weight_;
  }

 private:
  std::vector<cv::Point3d> object_;
  const CheckerboardView& view_;
  int offset_;
  double weight_ = 1.0;
  mutable std::vector<cv::Point2d> projected_main_, projected_aux_;
};

struct PhaseSample {
  cv::Point2d pixel;
  double phase_main = 0;
  double gradient = 1;  // |∇Φaux| at the initial match (rad per aux pixel)
  bool inlier = true;
};

class PhaseGroup final : public ResidualGroup {
 public:
  PhaseGroup(const PlanePoseObservation& pose, int offset)
      : aux_phase_(pose.phase_aux), offset_(offset) {}

  int localOffset() const override { return offset_; }
  int localSize() const override { return kPlaneUnknowns; }
  double localStep(int /*i*/) const override { return kPlaneStep; }

  void setSamples(std::vector<PhaseSample> samples) {
    samples_ = std::move(samples);
    pixels_.clear();
    for (const auto& s : samples_)
      pixels_.push_back(s.pixel);
    cached_main_.fill(std::numeric_limits<double>::quiet_NaN());
  }
  std::vector<PhaseSample>& samples() { return samples_; }

  // Weighting: residuals in px are divided by sigma; a sample whose aux
  // position falls on an invalid phase counts as `cap_px`.
  void setSigma(double sigma_px, double cap_px) {
    weight_ = 1.0 / sigma_px;
    cap_px_ = cap_px;
  }

  // Unweighted across-fringe aux-pixel residuals of the inlier samples (NaN
  // when the aux phase there is invalid); `aux_positions` optional.
  void pixelResiduals(const Vector& x, std::vector<double>& r,
                      std::vector<cv::Point2d>* aux_positions = nullptr) {
    updateRays(x);
    const cv::Vec3d q = vec3At(x, offset_);
    points_.clear();
    for (const auto& ray : rays_) {
      const double s = q.dot(ray);
      points_.push_back(ray * (1.0 / s));
    }
    const CameraParams aux = cameraAt(x, kAuxOffset);
    cv::projectPoints(points_, vec3At(x, kRotationOffset), vec3At(x, kTranslationOffset), aux.k,
                      aux.dist, projected_);
    r.clear();
    if (aux_positions) aux_positions->clear();
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      if (!samples_[i].inlier) continue;
      const double phase = sampleBilinear(aux_phase_, projected_[i].x, projected_[i].y);
      r.push_back((phase - samples_[i].phase_main) / samples_[i].gradient);
      if (aux_positions) aux_positions->push_back(projected_[i]);
    }
  }

  void evaluate(const Vector& x, std::vector<double>& r) override {
    pixelResiduals(x, r);
    for (double& v : r)
      v = std::isfinite(v) ? v * weight_ : cap_px_ * weight_;
  }

  const cv::Mat& auxPhase() const { return aux_phase_; }

 private:
  // The main rays depend only on the main intrinsics: undistort again only
  // when they changed.
  void updateRays(const Vector& x) {
    std::array<double, kIntrinsics> main{};
    for (int i = 0; i < kIntrinsics; ++i)
      main[static_cast<std::size_t>(i)] = x[kMainOffset + i];
    if (main == cached_main_) return;
    cached_main_ = main;
    const CameraParams camera = cameraAt(x, kMainOffset);
    std::vector<cv::Point2d> normalised;
    cv::undistortPoints(pixels_, normalised, camera.k, camera.dist, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT, kUndistortIterations, 0));
    rays_.clear();
    for (const auto& n : normalised)
      rays_.emplace_back(n.x, n.y, 1.0);
  }

  const cv::Mat& aux_phase_;
  int offset_;
  double weight_ = 1.0;
  double cap_px_ = 1.0;
  std::vector<PhaseSample> samples_;
  std::vector<cv::Point2d> pixels_;
  std::array<double, kIntrinsics> cached_main_{};
  std::vector<cv::Vec3d> rays_;
  std::vector<cv::Point3d> points_;
  std::vector<cv::Point2d> projected_;
};

double rms(const std::vector<double>& values) {
  double sum = 0;
  std::size_t n = 0;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    sum += v * v;
    ++n;
  }
  return n ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
}

double robustSigma(std::vector<double> values) {
  values.erase(
      std::remove_if(values.begin(), values.end(), [](double v) { return !std::isfinite(v); }),
      values.end());
  if (values.empty()) return 0.0;
  for (double& v : values)
    v = std::abs(v);
  const auto mid = values.begin() + static_cast<long>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return 1.4826 * *mid;
}

// Gauss–Newton with Levenberg–Marquardt damping over the free unknowns.
class Adjustment {
 public:
  Adjustment(Vector x, std::vector<bool> free, std::vector<ResidualGroup*> groups,
             std::array<double, kGlobals> global_steps)
      : x_(std::move(x)), free_(std::move(free)), groups_(std::move(groups)), steps_(global_steps) {
    for (int i = 0; i < static_cast<int>(x_.size()); ++i) {
      reduced_.push_back(free_[static_cast<std::size_t>(i)] ? unknowns_++ : -1);
    }
  }

  const Vector& x() const { return x_; }
  int unknowns() const { return unknowns_; }

  // Returns the iterations done; `converged` when the cost stopped decreasing.
  int run(int max_iterations, bool& converged) {
    converged = false;
    double lambda = 1e-4;
    double cost = totalCost(x_);
    int it = 0;
    for (; it < max_iterations; ++it) {
      Matrix h = Matrix::Zero(unknowns_, unknowns_);
      Vector g = Vector::Zero(unknowns_);
      assemble(h, g);
      bool accepted = false;
      while (lambda < 1e12) {
        Matrix damped = h;
        for (int i = 0; i < unknowns_; ++i)
          damped(i, i) += lambda * std::max(h(i, i), 1e-12);
        const Vector delta = damped.ldlt().solve(-g);
        Vector trial = x_;
        for (int i = 0; i < static_cast<int>(x_.size()); ++i) {
          const int k = reduced_[static_cast<std::size_t>(i)];
          if (k >= 0) trial[i] += delta[k];
        }
        const double trial_cost = totalCost(trial);
        if (std::isfinite(trial_cost) && trial_cost < cost) {
          const double gain = (cost - trial_cost) / cost;
          x_ = std::move(trial);
          cost = trial_cost;
          lambda = std::max(lambda / 10.0, 1e-12);
          accepted = true;
          if (gain < 1e-8) converged = true;
          break;
        }
        lambda *= 10.0;
      }
      if (!accepted) converged = true;  // no step lowers the cost: a minimum
      if (converged) return it + 1;
    }
    return it;
  }

 private:
  double totalCost(const Vector& x) {
    double cost = 0;
    for (ResidualGroup* group : groups_) {
      group->evaluate(x, r0_);
      for (double v : r0_)
        cost += v * v;
    }
    return cost;
  }

  // Columns of the Jacobian of one group by central differences.
  void column(ResidualGroup& group, int parameter, double step, std::vector<double>& out) {
    Vector xp = x_;
    xp[parameter] += step;
    group.evaluate(xp, rp_);
    xp[parameter] = x_[parameter] - step;
    group.evaluate(xp, rm_);
    out.resize(rp_.size());
    for (std::size_t i = 0; i < rp_.size(); ++i)
      out[i] = (rp_[i] - rm_[i]) / (2.0 * step);
  }

  void assemble(Matrix& h, Vector& g) {
    for (ResidualGroup* group : groups_) {
      group->evaluate(x_, r0_);
      const auto rows = static_cast<Eigen::Index>(r0_.size());
      std::vector<int> columns;  // reduced indices
      std::vector<std::pair<int, double>> parameters;
      for (int p = 0; p < kGlobals; ++p) {
        if (free_[static_cast<std::size_t>(p)])
          parameters.emplace_back(p, steps_[static_cast<std::size_t>(p)]);
      }
      for (int i = 0; i < group->localSize(); ++i)
        parameters.emplace_back(group->localOffset() + i, group->localStep(i));
      Matrix j(rows, static_cast<Eigen::Index>(parameters.size()));
      std::vector<double> col;
      for (std::size_t c = 0; c < parameters.size(); ++c) {
        column(*group, parameters[c].first, parameters[c].second, col);
        for (Eigen::Index i = 0; i < rows; ++i)
          j(i, static_cast<Eigen::Index>(c)) = col[static_cast<std::size_t>(i)];
        columns.push_back(reduced_[static_cast<std::size_t>(parameters[c].first)]);
      }
      const Eigen::Map<const Vector> r(r0_.data(), rows);
      const Matrix jtj = j.transpose() * j;
      const Vector jtr = j.transpose() * r;
      for (std::size_t a = 0; a < columns.size(); ++a) {
        g[columns[a]] += jtr[static_cast<Eigen::Index>(a)];
        for (std::size_t b = 0; b < columns.size(); ++b)
          h(columns[a], columns[b]) +=
              jtj(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
      }
    }
  }

  Vector x_;
  std::vector<bool> free_;
  std::vector<ResidualGroup*> groups_;
  std::array<double, kGlobals> steps_;
  std::vector<int> reduced_;
  int unknowns_ = 0;
  std::vector<double> r0_, rp_, rm_;
};

void checkInputs(const StereoGeometry& initial, const CheckerboardObservations& boards,
                 const std::vector<PlanePoseObservation>& poses) {
  if (boards.views.size() < 3)
    throw std::invalid_argument("stereo refinement: at least 3 checkerboard views are needed");
  if (poses.size() < 2)
    throw std::invalid_argument("stereo refinement: at least 2 plane poses are needed");
  for (const auto& view : boards.views) {
    if (view.main.size() != boards.object.size() || view.aux.size() != boards.object.size())
      throw std::invalid_argument(
          "stereo refinement: a checkerboard view's corner count differs from the board's");
  }
  const cv::Size size = initial.main.image_size;
  for (const auto& pose : poses) {
    if (pose.phase_main.type() != CV_32FC1 || pose.phase_main.size() != size ||
        pose.phase_aux.type() != CV_32FC1 || pose.phase_aux.size() != initial.aux.image_size)
      throw std::invalid_argument(
          "stereo refinement: phase maps must be CV_32F of the calibrated image size");
    if (!pose.use.empty() && (pose.use.type() != CV_8UC1 || pose.use.size() != size))
      throw std::invalid_argument(
          "stereo refinement: the use mask must be CV_8U of the image size");
  }
}

// A regular grid of valid main pixels, about `wanted` of them.
std::vector<PhaseSample> gridSamples(const PlanePoseObservation& pose, int wanted) {
  const cv::Mat& phase = pose.phase_main;
  auto usable = [&](int u, int v) {
    return std::isfinite(phase.at<float>(v, u)) &&
           (pose.use.empty() || pose.use.at<std::uint8_t>(v, u));
  };
  std::size_t count = 0;
  for (int v = 0; v < phase.rows; ++v)
    for (int u = 0; u < phase.cols; ++u)
      count += usable(u, v) ? 1 : 0;
  const int stride =
      std::max(1, static_cast<int>(std::sqrt(static_cast<double>(count) / std::max(wanted, 1))));
  std::vector<PhaseSample> samples;
  for (int v = stride / 2; v < phase.rows; v += stride)
    for (int u = stride / 2; u < phase.cols; u += stride)
      if (usable(u, v)) samples.push_back({cv::Point2d(u, v), phase.at<float>(v, u), 1.0, true});
  return samples;
}

// Each sample's across-fringe scale: |∇Φaux| where the initial geometry puts
// it. Samples that fall outside the valid aux phase are dropped.
void measureGradients(PhaseGroup& group, const Vector& x) {
  std::vector<double> r;
  std::vector<cv::Point2d> positions;
  group.pixelResiduals(x, r, &positions);
  std::vector<PhaseSample> kept;
  const cv::Mat& map = group.auxPhase();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const cv::Point2d p = positions[i];
    const double gx = (sampleBilinear(map, p.x + 1, p.y) - sampleBilinear(map, p.x - 1, p.y)) / 2;
    const double gy = (sampleBilinear(map, p.x, p.y + 1) - sampleBilinear(map, p.x, p.y - 1)) / 2;
    const double gradient = std::hypot(gx, gy);
    if (!std::isfinite(r[i]) || !std::isfinite(gradient) || gradient < 1e-6) continue;
    PhaseSample s = group.samples()[i];
    s.gradient = gradient;
    kept.push_back(s);
  }
  group.setSamples(std::move(kept));
}

ResidualSummary summarise(std::vector<BoardGroup>& boards, std::vector<PhaseGroup>& poses,
                          const Vector& x, std::vector<double>* pose_rms = nullptr) {
  ResidualSummary s;
  std::vector<double> main, aux, r, all;
  for (auto& board : boards) {
    board.pixelResiduals(x, r);
    const std::size_t half = r.size() / 2;
    main.insert(main.end(), r.begin(), r.begin() + static_cast<long>(half));
    aux.insert(aux.end(), r.begin() + static_cast<long>(half), r.end());
  }
  for (auto& pose : poses) {
    pose.pixelResiduals(x, r);
    if (pose_rms) pose_rms->push_back(rms(r));
    all.insert(all.end(), r.begin(), r.end());
  }
  // A corner residual is a 2-vector: RMS over corners of its length.
  s.board_main_rms_px = rms(main) * std::sqrt(2.0);
  s.board_aux_rms_px = rms(aux) * std::sqrt(2.0);
  s.phase_rms_px = rms(all);
  s.phase_samples = all.size();
  return s;
}

}  // namespace

StereoRefinementResult refineStereoWithPhase(const StereoGeometry& initial,
                                             const CheckerboardObservations& boards,
                                             const std::vector<PlanePoseObservation>& poses,
                                             const StereoRefinementOptions& options) {
  checkInputs(initial, boards, poses);
  const std::array<bool, kIntrinsics> free_intrinsics = freeIntrinsics(options.model);

  const int board_offset = kGlobals;
  const int plane_offset = board_offset + kBoardUnknowns * static_cast<int>(boards.views.size());
  const int total = plane_offset + kPlaneUnknowns * static_cast<int>(poses.size());
  Vector x = Vector::Zero(total);
  putCamera(initial.main, x, kMainOffset);
  putCamera(initial.aux, x, kAuxOffset);
  cv::Vec3d rvec;
  cv::Rodrigues(initial.rotation, rvec);
  for (int i = 0; i < 3; ++i) {
    x[kRotationOffset + i] = rvec[i];
    x[kTranslationOffset + i] = initial.translation[i];
  }
  std::vector<bool> free(static_cast<std::size_t>(total), true);
  std::array<double, kGlobals> steps{};
  // Indices as std::size_t from the start (the offsets are small non-negative constants).
  const auto at = [](int offset, std::size_t i) { return static_cast<std::size_t>(offset) + i; };
  for (std::size_t i = 0; i < static_cast<std::size_t>(kIntrinsics); ++i) {
    free[at(kMainOffset, i)] = free_intrinsics[i];
    free[at(kAuxOffset, i)] = free_intrinsics[i];
    steps[at(kMainOffset, i)] = kIntrinsicSteps[i];
    steps[at(kAuxOffset, i)] = kIntrinsicSteps[i];
  }
  for (std::size_t i = 0; i < 3; ++i) {
    steps[at(kRotationOffset, i)] = kRotationStep;
    steps[at(kTranslationOffset, i)] = kTranslationStep;
  }

  // Board poses from the main camera (PnP with the initial intrinsics).
  std::vector<BoardGroup> board_groups;
  for (std::size_t b = 0; b < boards.views.size(); ++b) {
    const int offset = board_offset + kBoardUnknowns * static_cast<int>(b);
    cv::Vec3d r, t;
    cv::solvePnP(boards.object, boards.views[b].main, initial.main.camera_matrix,
                 initial.main.dist_coeffs, r, t);
    for (int i = 0; i < 3; ++i) {
      x[offset + i] = r[i];
      x[offset + 3 + i] = t[i];
    }
    board_groups.emplace_back(boards, b, offset);
  }
  // Planes as q = n / d.
  std::vector<PhaseGroup> phase_groups;
  phase_groups.reserve(poses.size());
  for (std::size_t p = 0; p < poses.size(); ++p) {
    const int offset = plane_offset + kPlaneUnknowns * static_cast<int>(p);
    const Plane& plane = poses[p].plane;
    const Eigen::Vector3d n = plane.normal.normalized();
    const double d = n.dot(plane.point);
    if (!(std::abs(d) > 1e-6))
      throw std::invalid_argument("stereo refinement: a pose's plane passes through the camera");
    for (int i = 0; i < 3; ++i)
      x[offset + i] = n[i] / d;
    phase_groups.emplace_back(poses[p], offset);
    phase_groups.back().setSamples(gridSamples(poses[p], options.samples_per_pose));
    measureGradients(phase_groups.back(), x);
    if (phase_groups.back().samples().empty()) {
      throw std::runtime_error("stereo refinement: plane pose " + std::to_string(p + 1) +
                               " has no main pixel whose phase the aux camera sees");
    }
  }

  StereoRefinementResult result;
  result.before = summarise(board_groups, phase_groups, x);
  std::vector<ResidualGroup*> groups;
  groups.reserve(board_groups.size() + phase_groups.size());
  for (auto& g : board_groups)
    groups.push_back(&g);
  for (auto& g : phase_groups)
    groups.push_back(&g);

  // Two solves: the first weighted by the initial RMS of each kind, the
  // second by the RMS it leaves, without the phase outliers it reveals.
  double board_sigma = std::max(
      std::hypot(result.before.board_main_rms_px, result.before.board_aux_rms_px) / 2, 1e-3);
  double phase_sigma = std::max(result.before.phase_rms_px, 1e-4);
  for (int round = 0; round < 2; ++round) {
    for (auto& g : board_groups)
      g.setSigma(board_sigma);
    for (auto& g : phase_groups)
      g.setSigma(phase_sigma, options.outlier_sigmas * phase_sigma);
    Adjustment adjustment(x, free, groups, steps);
    bool converged = false;
    result.iterations += adjustment.run(options.max_iterations, converged);
    result.converged = converged;
    result.unknowns = static_cast<std::size_t>(adjustment.unknowns());
    x = adjustment.x();
    if (round == 1) break;
    // Re-weight and trim.
    std::vector<double> all, r;
    for (auto& g : phase_groups) {
      g.pixelResiduals(x, r);
      all.insert(all.end(), r.begin(), r.end());
    }
    phase_sigma = std::max(robustSigma(all), 1e-4);
    for (auto& g : phase_groups) {
      g.pixelResiduals(x, r);
      std::size_t i = 0;
      for (auto& s : g.samples()) {
        if (!s.inlier) continue;
        const double v = r[i++];
        s.inlier = std::isfinite(v) && std::abs(v) <= options.outlier_sigmas * phase_sigma;
      }
    }
    const ResidualSummary mid = summarise(board_groups, phase_groups, x);
    board_sigma = std::max(std::hypot(mid.board_main_rms_px, mid.board_aux_rms_px) / 2, 1e-3);
    phase_sigma = std::max(mid.phase_rms_px, 1e-4);
  }
  result.after = summarise(board_groups, phase_groups, x, &result.pose_phase_rms_px);

  const CameraParams main = cameraAt(x, kMainOffset);
  const CameraParams aux = cameraAt(x, kAuxOffset);
  result.geometry.main = {main.k, main.dist, initial.main.image_size};
  result.geometry.aux = {aux.k, aux.dist, initial.aux.image_size};
  cv::Rodrigues(vec3At(x, kRotationOffset), result.geometry.rotation);
  result.geometry.translation = vec3At(x, kTranslationOffset);
  for (std::size_t p = 0; p < poses.size(); ++p) {
    const cv::Vec3d q = vec3At(x, plane_offset + kPlaneUnknowns * static_cast<int>(p));
    const double norm = cv::norm(q);
    Plane plane;
    plane.normal = Eigen::Vector3d(q[0], q[1], q[2]) / norm;
    plane.point = plane.normal / norm;
    result.planes.push_back(plane);
  }
  return result;
}

}  // namespace cylscan::algo
