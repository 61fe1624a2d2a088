// SPDX-License-Identifier: Apache-2.0
// The calibration solves (firmware/stereo_solve.hpp, firmware/quasi_solve.hpp):
// on synthetic corners with known cameras, and on what the virtual head
// captures (checkerboard stills, plane scans), against its true geometry.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "drivers/board.hpp"
#include "drivers/board_profile.hpp"
#include "drivers/sim/geometry.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/bundle_sink.hpp"
#include "firmware/checkerboard_corners.hpp"
#include "firmware/quasi_solve.hpp"
#include "firmware/scan_plan.hpp"
#include "firmware/shipped_boards.hpp"
#include "firmware/stereo_solve.hpp"
#include "formats/input_error.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using test_support::TempDir;

// Every call of a progress callback, in order.
struct ProgressLog {
  std::vector<double> values;
  SolveProgress callback() {
    return [this](double done) { values.push_back(done); };
  }
  // 0 first, 1 last, never going back.
  void expectZeroToOne(std::size_t at_least) const {
    ASSERT_GE(values.size(), at_least);
    EXPECT_EQ(values.front(), 0.0);
    EXPECT_EQ(values.back(), 1.0);
    EXPECT_TRUE(std::is_sorted(values.begin(), values.end()));
  }
};

// ------------------------------------------------------------ synthetic corners

// Two known cameras and views of a 9 × 6 board projected into both with
// Gaussian corner noise: what the solve must give back is known exactly.
struct SyntheticRig {
  formats::CheckerboardInfo board{9, 6, 25.0};
  cv::Size size{640, 480};
  cv::Matx33d k_main{800, 0, 330, 0, 805, 235, 0, 0, 1};
  cv::Vec<double, 5> d_main{-0.08, 0.05, 0, 0, 0};
  // Different from main's in every parameter: a swap of the cameras shows.
  cv::Matx33d k_aux{780, 0, 310, 0, 778, 250, 0, 0, 1};
  cv::Vec<double, 5> d_aux{-0.05, 0.02, 0, 0, 0};
  cv::Vec3d r_aux{0.01, 0.12, 0.005};  // Rodrigues, X_aux = R X_main + T
  cv::Vec3d t_aux{-150, 2, 15};
  double noise_px = 0.05;

  cv::Matx33d rotation() const {
    cv::Matx33d r;
    cv::Rodrigues(r_aux, r);
    return r;
  }

  // `count` views whose corners are all well inside both images.
  StereoCorners views(int count) const {
    const std::vector<cv::Point3f> object = boardPoints(board);
    const cv::Point3d centre(4 * board.square_mm, 2.5 * board.square_mm, 0);
    cv::RNG rng(7);
    StereoCorners out;
    out.image_size = size;
    for (int i = 0; static_cast<int>(out.pairs.size()) < count && i < 500; ++i) {
      const cv::Vec3d rvec(0.45 * std::sin(i * 2.1), 0.45 * std::sin(i * 1.3 + 0.7),
                           0.2 * std::sin(i * 0.9));
      cv::Matx33d rb;
      cv::Rodrigues(rvec, rb);
      const cv::Vec3d at(72 + 30 * std::sin(i * 1.7), 25 * std::cos(i * 2.3),
                         620 + 160 * std::fmod(i * 0.618034, 1.0));
      const cv::Vec3d tvec = at - rb * cv::Vec3d(centre.x, centre.y, centre.z);
      // The aux view of the board: X_aux = R (Rb P + t) + T.
      const cv::Matx33d ra = rotation() * rb;
      const cv::Vec3d ta = rotation() * tvec + t_aux;
      cv::Vec3d rvec_aux;
      cv::Rodrigues(ra, rvec_aux);
      Corners main, aux;
      cv::projectPoints(object, rvec, tvec, k_main, d_main, main);
      cv::projectPoints(object, rvec_aux, ta, k_aux, d_aux, aux);
      const auto inside = [&](const Corners& corners) {
        return std::all_of(corners.begin(), corners.end(), [&](const cv::Point2f& p) {
          return p.x > 20 && p.y > 20 && p.x < size.width - 21 && p.y < size.height - 21;
        });
      };
      if (!inside(main) || !inside(aux)) continue;
      for (Corners* corners : {&main, &aux}) {
        for (cv::Point2f& p : *corners) {
          p.x += static_cast<float>(rng.gaussian(noise_px));
          p.y += static_cast<float>(rng.gaussian(noise_px));
        }
      }
      out.pairs.push_back({"v" + std::to_string(i), main, aux});
    }
    out.pair_count = out.pairs.size();
    return out;
  }
};

// The solve's estimate is within `sigmas` of its own standard deviations of
// the truth, and those deviations are small.
void expectIntrinsics(const StereoCameraResult& fit, const cv::Matx33d& truth, const char* camera) {
  SCOPED_TRACE(camera);
  const cv::Matx33d& k = fit.camera_matrix;
  const IntrinsicSigmas& s = fit.sigma;
  // 0.05 px of corner noise on 54 corners × 12 views: OpenCV puts the focal
  // lengths and principal point at ~1 px (they trade against the distortion
  // coefficients over these views); 2 px is 0.25 % of f. Within 4 of its own
  // σ of the truth: this deterministic draw is within 1σ, while a bias (a
  // wrong model, swapped cameras, the board's scale) is tens of σ.
  constexpr double kSigmas = 4.0;
  for (const double sigma : {s.fx, s.fy, s.cx, s.cy}) {
    EXPECT_GT(sigma, 0.0);
    EXPECT_LT(sigma, 2.0);
  }
  EXPECT_NEAR(k(0, 0), truth(0, 0), kSigmas * s.fx);
  EXPECT_NEAR(k(1, 1), truth(1, 1), kSigmas * s.fy);
  EXPECT_NEAR(k(0, 2), truth(0, 2), kSigmas * s.cx);
  EXPECT_NEAR(k(1, 2), truth(1, 2), kSigmas * s.cy);
  // The residuals are the corner noise: RMS over x and y of 0.05 px each.
  EXPECT_NEAR(fit.rms_px, 0.05 * std::sqrt(2.0), 0.02);
}

TEST(StereoSolve, RecoversKnownCamerasFromProjectedCorners) {
  const SyntheticRig rig;
  StereoCorners corners = rig.views(12);
  ASSERT_EQ(corners.pairs.size(), 12u);
  ProgressLog progress;
  const StereoSolveResult result =
      solveStereo(rig.board, std::move(corners), {}, progress.callback());

  EXPECT_EQ(result.image_size, rig.size);
  EXPECT_EQ(result.pair_count, 12u);
  EXPECT_EQ(result.views.size(), 12u);
  EXPECT_TRUE(result.rejected.empty());
  expectIntrinsics(result.main, rig.k_main, "main");
  expectIntrinsics(result.aux, rig.k_aux, "aux");
  // The file holds what the result says.
  EXPECT_EQ(result.calibration.camera_matrix_main, result.main.camera_matrix);
  EXPECT_EQ(result.calibration.camera_matrix_aux, result.aux.camera_matrix);
  EXPECT_EQ(result.calibration.image_width, 640);
  // The pair, R and T alone with the intrinsics fixed, inherits their ~1 px
  // errors: ~0.1° of each camera's direction at f ≈ 800, and the baseline's
  // scale with the focal lengths (0.1 %). 0.3° and 1.5 mm (1 % of 150 mm)
  // allow that; a transposed R (14°) or a sign of T does not pass.
  EXPECT_LT(cv::norm(result.calibration.T - rig.t_aux), 1.5);
  EXPECT_NEAR(result.baseline_mm, cv::norm(rig.t_aux), 1.5);
  cv::Vec3d angle;
  cv::Rodrigues(result.calibration.R * rig.rotation().t(), angle);
  EXPECT_LT(cv::norm(angle) * 180 / CV_PI, 0.3);
  for (const StereoViewResult& view : result.views)
    EXPECT_LT(view.stereo_rms_px, 0.2) << view.id;
  progress.expectZeroToOne(3);
}

TEST(StereoSolve, DropsAReprojectionOutlierAndSaysWhy) {
  const SyntheticRig rig;
  StereoCorners corners = rig.views(10);
  // A misdetected board: aux's corners of one pair shifted by up to 6 px.
  for (std::size_t i = 0; i < corners.pairs[3].aux.size(); ++i)
    corners.pairs[3].aux[i].x += static_cast<float>(6.0 * std::sin(static_cast<double>(i)));
  const std::string bad = corners.pairs[3].id;
  const StereoSolveResult result = solveStereo(rig.board, std::move(corners));
  ASSERT_EQ(result.rejected.size(), 1u);
  EXPECT_EQ(result.rejected[0].id, bad);
  EXPECT_NE(result.rejected[0].reason.find("reprojection outlier"), std::string::npos);
  EXPECT_EQ(result.views.size(), 9u);
  EXPECT_EQ(result.pair_count, 10u);
  for (const StereoViewResult& view : result.views)
    EXPECT_NE(view.id, bad);
  // Without it, aux is as good as the clean rig's.
  expectIntrinsics(result.aux, rig.k_aux, "aux");
}

TEST(StereoSolve, TooFewPairsIsATypedErrorListingTheRejectedPairs) {
  const SyntheticRig rig;
  StereoCorners corners = rig.views(4);
  corners.rejected.push_back({"x9", "corners not found in aux"});
  corners.pair_count = 5;
  StereoSolveOptions options;
  options.min_pairs = 6;
  try {
    solveStereo(rig.board, std::move(corners), options);
    FAIL() << "4 pairs must not be enough for 6";
  } catch (const TooFewPairs& e) {
    EXPECT_EQ(e.usable(), 4u);
    EXPECT_EQ(e.needed(), 6);
    EXPECT_FALSE(e.afterOutliers());
    ASSERT_EQ(e.rejected().size(), 1u);
    EXPECT_EQ(e.reasons(), "; x9: corners not found in aux");
    EXPECT_NE(std::string(e.what()).find("only 4 usable checkerboard pairs, at least 6"),
              std::string::npos)
        << e.what();
  }
}

TEST(StereoSolve, ABoardFoundNowhereIsATypedErrorAndABadModelABadArgument) {
  const SyntheticRig rig;
  StereoCorners none;
  none.image_size = rig.size;
  none.pair_count = 7;
  for (int i = 0; i < 7; ++i)
    none.rejected.push_back({std::to_string(i), "corners not found in main and aux"});
  try {
    solveStereo(rig.board, none);
    FAIL() << "no pair has the board";
  } catch (const BoardNotFound& e) {
    EXPECT_EQ(e.pairCount(), 7u);
    EXPECT_NE(std::string(e.what()).find("9 x 6 inner corners"), std::string::npos) << e.what();
  }
  StereoSolveOptions options;
  options.model = "k1k2k3k4";
  EXPECT_THROW(solveStereo(rig.board, rig.views(8), options), std::invalid_argument);
}

// ------------------------------------------------------------- the virtual head

// The shipped virtual head at 320 × 256 (the same fields of view) as a board,
// with the acquisition loop that captures on it: checkerboard stills and
// plane scans, as a calibration session takes them.
class VirtualHeadRig {
 public:
  VirtualHeadRig() : board_(drivers::Board::open(profile())), acquisition_(board_) {
    options_ = scanOptionsFrom(board_.profile());
    options_.cameras = {"main", "aux"};
    plan_ = planScan(options_, board_.profile().stage);
  }

  sim::VirtualHead& head() { return *board_.virtualHead(); }
  cv::Size size() {
    return {head().cameraModel("main").width(), head().cameraModel("main").height()};
  }

  // A still of main and aux of the board at `pose`, under room light.
  StereoPairImages boardPair(const std::string& id, const sim::Checkerboard& pose) {
    head().setScene(scene("board", {{"board", pose, 0.8}}, 0.7));
    StillOptions still;
    still.cameras = {"main", "aux"};
    const std::vector<cv::Mat> images = acquisition_.still(still);
    return {id, images.at(0), images.at(1)};
  }

  // Board poses well inside both images and facing both cameras (deterministic).
  std::vector<sim::Checkerboard> boardPoses(int count) {
    std::vector<sim::Checkerboard> poses;
    const double margin = 0.04 * size().width;
    for (int i = 0; static_cast<int>(poses.size()) < count && i < 400; ++i) {
      sim::Checkerboard b;
      const double z = 530 + 110 * std::fmod(i * 0.618034, 1.0);
      b.center = sim::Vec3(14 * std::sin(i * 1.7), 10 * std::cos(i * 2.3), z);
      b.rotation = sim::rotationFromVectorDeg(
          {22 * std::sin(i * 2.1), 25 * std::sin(i * 1.3 + 0.7), 10 * std::sin(i * 0.9 + 0.3)});
      bool inside = true;
      for (const char* name : {"main", "aux"}) {
        const sim::CameraModel& cam = head().cameraModel(name);
        const sim::Vec3 towards = (cam.centre() - b.center).normalized();
        inside = inside && std::abs(towards.dot(b.rotation.col(2))) > std::cos(50 * sim::kDeg);
        for (const sim::Vec3& c : b.corners()) {
          const auto px = cam.project(c);
          inside = inside && px && px->x() > margin && px->y() > margin &&
                   px->x() < cam.width() - 1 - margin && px->y() < cam.height() - 1 - margin;
        }
      }
      if (inside) poses.push_back(b);
    }
    return poses;
  }

  // The plane pose `i` of `count` (depths 540–620 mm, tilts up to 12°) as a
  // capture bundle of main and aux in `dir`; returns the true plane.
  sim::Plane scanPlane(const fs::path& dir, int i, int count) {
    const double z = 540.0 + 80.0 * i / (count - 1);
    const sim::Mat3 r = sim::rotationFromVectorDeg({10 * std::sin(i * 2.4 + 0.5), 0, 0}) *
                        sim::rotationFromVectorDeg({0, 12 * std::sin(i * 1.7 + 1.1), 0});
    sim::Plane plane{sim::Vec3(0, 0, z), r * sim::Vec3(0, 0, -1), std::nullopt};
    head().setScene(scene("plane", {{"plane", plane, 0.8}}, 0.03));
    BundleSink bundle(dir, plan_, options_.cameras, nlohmann::json::object());
    acquisition_.run(options_, plan_, bundle);
    bundle.commit();
    return plane;
  }

  // The head's own stereo geometry, as a stereo calibration file holds it.
  formats::StereoCalibration stereoTruth() {
    const sim::CameraModel& main = head().cameraModel("main");
    const sim::CameraModel& aux = head().cameraModel("aux");
    formats::StereoCalibration c;
    c.image_width = main.width();
    c.image_height = main.height();
    c.camera_matrix_main = intrinsics(main.params());
    c.dist_coeffs_main = {main.params().k1, main.params().k2, 0, 0, 0};
    c.camera_matrix_aux = intrinsics(aux.params());
    c.dist_coeffs_aux = {aux.params().k1, aux.params().k2, 0, 0, 0};
    const sim::Mat3 r = aux.rotationCamFromMain() * main.rotationCamFromMain().transpose();
    const sim::Vec3 t = -aux.rotationCamFromMain() * (aux.centre() - main.centre());
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        c.R(i, j) = r(i, j);
      c.T[i] = t[i];
    }
    return c;
  }

  static cv::Matx33d intrinsics(const sim::CameraParams& p) {
    return {p.fx, 0, p.cx, 0, p.fy, p.cy, 0, 0, 1};
  }

 private:
  static drivers::BoardProfile profile() {
    drivers::BoardProfile p = drivers::loadBoardProfile(shippedBoard("sim"));
    p.sim->head = sim::withResolution(p.sim->head, 320, 256);
    for (drivers::CameraProfile& camera : p.cameras) {
      for (const sim::CameraParams& model : p.sim->head.cameras) {
        if (model.name != camera.device) continue;
        camera.config.width = model.width;
        camera.config.height = model.height;
        camera.config.bit_depth = model.bit_depth;
      }
    }
    return p;
  }

  static sim::Scene scene(const std::string& name, std::vector<sim::SceneObject> objects,
                          double ambient) {
    sim::Scene s;
    s.name = name;
    s.ambient = ambient;
    s.objects = std::move(objects);
    return s;
  }

  drivers::Board board_;
  Acquisition acquisition_;  // on board_: declared after it
  ScanOptions options_;
  ScanPlan plan_;
};

TEST(PairCorners, FoundInBothStillsOrNamedWhereMissing) {
  VirtualHeadRig rig;
  const formats::CheckerboardInfo info{9, 6, 12.0};  // sim::Checkerboard's
  const StereoPairImages pair = rig.boardPair("00", rig.boardPoses(1).at(0));
  const PairDetection found = detectPairCorners(info, pair.main, pair.aux);
  ASSERT_TRUE(found.found()) << found.missing();
  EXPECT_EQ(found.main->size(), 54u);
  EXPECT_EQ(found.aux->size(), 54u);
  EXPECT_EQ(found.missing(), "");
  // aux's corners run in main's order: both grids start at the same end.
  EXPECT_GT((found.main->back() - found.main->front()).dot(found.aux->back() - found.aux->front()),
            0.0f);

  const cv::Mat blank(pair.aux.size(), pair.aux.type(), cv::Scalar(90));
  const PairDetection half = detectPairCorners(info, pair.main, blank);
  EXPECT_FALSE(half.found());
  EXPECT_TRUE(half.main.has_value());
  EXPECT_EQ(half.missing(), "aux");
  EXPECT_EQ(detectPairCorners(info, blank, blank).missing(), "main and aux");

  const cv::Mat smaller(100, 120, CV_8U, cv::Scalar(0));
  EXPECT_THROW(detectPairCorners(info, pair.main, smaller), std::invalid_argument);
  const cv::Mat grey_alpha(pair.aux.size(), CV_8UC2, cv::Scalar(0, 255));
  EXPECT_THROW(detectPairCorners(info, pair.main, grey_alpha), std::invalid_argument);
}

TEST(StereoSolve, RecoversTheVirtualHeadFromItsOwnStills) {
  VirtualHeadRig rig;
  const formats::CheckerboardInfo info{9, 6, 12.0};
  std::vector<StereoPairImages> pairs;
  for (const sim::Checkerboard& pose : rig.boardPoses(10))
    pairs.push_back(rig.boardPair(std::to_string(pairs.size()), pose));
  // A pair where aux missed the board (a capture that failed) is rejected, not fatal.
  pairs.push_back({"blank", pairs[0].main, cv::Mat(pairs[0].aux.size(), CV_8U, cv::Scalar(90))});
  ASSERT_EQ(pairs.size(), 11u);

  ProgressLog progress;
  const StereoSolveResult result = solveStereo(info, pairs, {}, progress.callback());
  progress.expectZeroToOne(pairs.size() + 2);  // each pair's detection, then the fits

  ASSERT_EQ(result.rejected.size(), 1u);
  EXPECT_EQ(result.rejected[0].id, "blank");
  EXPECT_EQ(result.rejected[0].reason, "corners not found in aux");
  EXPECT_EQ(result.views.size(), 10u);
  EXPECT_EQ(result.image_size, cv::Size(320, 256));
  // The virtual head renders optics (blur, noise, sampling) of its own, so
  // the checkerboard calibration has errors of its own: the quick dataset
  // (`simulate --quick`, 14 pairs) gives main's fx 0.49 % and cx 9 px from
  // the truth. Its 12 mm lens sees ±8°, so at 320 px the principal point is
  // weakly determined: OpenCV's σ of cx is 5–10 px with these 10 pairs, and
  // the focal length's ~0.5 %. The checks: fx and fy within 1.5 % and 3σ,
  // the principal point within 3σ (σ under 15 px), the baseline within
  // 1.5 % (a wrong board scale moves it, not f).
  const formats::StereoCalibration truth = rig.stereoTruth();
  for (const auto& [name, fit, k] : {std::tuple{"main", &result.main, truth.camera_matrix_main},
                                     std::tuple{"aux", &result.aux, truth.camera_matrix_aux}}) {
    SCOPED_TRACE(name);
    const cv::Matx33d& e = fit->camera_matrix;
    const IntrinsicSigmas& s = fit->sigma;
    EXPECT_NEAR(e(0, 0) / k(0, 0), 1.0, 0.015);
    EXPECT_NEAR(e(1, 1) / k(1, 1), 1.0, 0.015);
    EXPECT_NEAR(e(0, 0), k(0, 0), 3 * s.fx);
    EXPECT_NEAR(e(1, 1), k(1, 1), 3 * s.fy);
    EXPECT_NEAR(e(0, 2), k(0, 2), 3 * s.cx);
    EXPECT_NEAR(e(1, 2), k(1, 2), 3 * s.cy);
    for (const double sigma : {s.fx, s.fy, s.cx, s.cy}) {
      EXPECT_GT(sigma, 0.0);
      EXPECT_LT(sigma, 15.0);
    }
    EXPECT_LT(fit->rms_px, 0.5);
  }
  EXPECT_NEAR(result.baseline_mm / cv::norm(truth.T), 1.0, 0.015);
}

// ---------------------------------------------------------------- quasi solve

// Six plane poses of the virtual head, scanned once for every test below.
class QuasiSolveTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<TempDir>();
    rig_ = std::make_unique<VirtualHeadRig>();
    for (int i = 0; i < kPoses; ++i) {
      bundles_.push_back(dir_->path() / ("pose" + std::to_string(i)));
      planes_.push_back(rig_->scanPlane(bundles_.back(), i, kPoses));
    }
  }
  static void TearDownTestSuite() {
    rig_.reset();
    dir_.reset();
    bundles_.clear();
    planes_.clear();
  }

  static constexpr int kPoses = 6;
  static inline std::unique_ptr<TempDir> dir_;
  static inline std::unique_ptr<VirtualHeadRig> rig_;
  static inline std::vector<fs::path> bundles_;
  static inline std::vector<sim::Plane> planes_;
};

TEST_F(QuasiSolveTest, CalibratesTheHeadFromItsPlanePoses) {
  ProgressLog progress;
  const QuasiSolveResult result =
      solveQuasiCalibration(rig_->stereoTruth(), bundles_, {}, progress.callback());
  progress.expectZeroToOne(kPoses + 3);  // each pose, then the fit and the residual pass

  const algo::QuasiCalibration& calib = result.calibration;
  EXPECT_EQ(calib.size(), cv::Size(320, 256));
  // The planes fill the view: nearly every pixel is seen in all six poses.
  EXPECT_GT(static_cast<double>(calib.validCount()), 0.8 * calib.size().area());
  // The cubic explains the poses to well under the phase noise's 0.1 mm (the
  // quick dataset's pooled RMSE is 0.049 mm), and the file says so.
  EXPECT_GT(result.pooled_rmse_mm, 0.0);
  EXPECT_LT(result.pooled_rmse_mm, 0.1);
  EXPECT_FLOAT_EQ(calib.info().pooled_rmse_mm, static_cast<float>(result.pooled_rmse_mm));
  EXPECT_GT(result.sensitivity_mm_per_rad, 0.0);
  EXPECT_GT(result.residual_pixels, 0u);
  EXPECT_TRUE(std::isfinite(calib.info().order_centre_rad));

  ASSERT_EQ(result.poses.size(), static_cast<std::size_t>(kPoses));
  for (std::size_t i = 0; i < result.poses.size(); ++i) {
    const QuasiPoseResult& pose = result.poses[i];
    SCOPED_TRACE(pose.bundle);
    EXPECT_EQ(pose.bundle, bundles_[i].string());
    EXPECT_LT(pose.rmse_mm, 0.2);
    EXPECT_GT(pose.main_valid_fraction, 0.8);
    EXPECT_GT(pose.aux_valid_fraction, 0.5);
    EXPECT_GT(pose.plane_inliers, pose.stereo_points / 2);
    EXPECT_GT(pose.target_pixels, 0u);
    EXPECT_GT(pose.order_residual.samples, 0u);
    // The stereo plane is the true one: with the true stereo geometry, within
    // a few tenths of a millimetre (the plane fit's RMSE is ~0.1 mm over
    // tens of thousands of points) and a tenth of a degree.
    const Eigen::Vector3d n = planes_[i].normal.normalized();
    EXPECT_LT(std::abs(n.dot(pose.plane.point - planes_[i].point)), 0.3);
    EXPECT_GT(std::abs(n.dot(pose.plane.normal.normalized())), std::cos(0.1 * sim::kDeg));
    const nlohmann::json json = quasiPoseJson(pose);
    EXPECT_EQ(json.at("rmse_mm").get<double>(), pose.rmse_mm);
    EXPECT_EQ(json.at("plane_inliers").get<std::size_t>(), pose.plane_inliers);
  }
}

TEST_F(QuasiSolveTest, TooFewPosesIsATypedBadRequest) {
  const std::vector<fs::path> five(bundles_.begin(), bundles_.begin() + 5);
  try {
    solveQuasiCalibration(rig_->stereoTruth(), five);
    FAIL() << "five poses must not be enough for six";
  } catch (const TooFewPoses& e) {
    EXPECT_EQ(e.given(), 5u);
    EXPECT_EQ(e.needed(), 6);
    EXPECT_STREQ(e.what(), "5 plane poses given, at least 6 are needed");
  }
  // A bad request, as the command line's exit status 2 needs.
  EXPECT_THROW(requireEnoughPoses(5, 6), std::invalid_argument);
  EXPECT_NO_THROW(requireEnoughPoses(6, 6));
}

TEST_F(QuasiSolveTest, OnePoseSixTimesCalibratesNoPixel) {
  // Every pixel's phase is the same in all six: no phase range to fit.
  const std::vector<fs::path> same(kPoses, bundles_[0]);
  EXPECT_THROW(solveQuasiCalibration(rig_->stereoTruth(), same), NoPixelCalibrated);
}

TEST_F(QuasiSolveTest, ImagesOfAnotherSizeNameTheStereoCalibration) {
  formats::StereoCalibration big = rig_->stereoTruth();
  big.image_width = 640;
  big.image_height = 512;
  QuasiSolveOptions options;
  options.stereo_file = "session/stereo.yaml";
  try {
    solveQuasiCalibration(big, bundles_, options);
    FAIL() << "the bundles are 320x256";
  } catch (const formats::InputError& e) {
    EXPECT_EQ(e.file(), options.stereo_file);
    EXPECT_NE(std::string(e.what()).find("320x256"), std::string::npos) << e.what();
  }
  // Without a file, the bundle's camera folder is named.
  try {
    solveQuasiCalibration(big, bundles_);
    FAIL() << "the bundles are 320x256";
  } catch (const formats::InputError& e) {
    EXPECT_EQ(e.file(), bundles_[0] / "main");
  }
}

}  // namespace
}  // namespace cylscan::firmware
