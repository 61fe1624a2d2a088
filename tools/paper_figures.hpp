// SPDX-License-Identifier: Apache-2.0
// The published figures of the paper (Choi, Kim, Hyun, "Cylindrical Mechanical
// Projector for Omnidirectional Fringe Projection Profilometry"),
// transcribed for `cylscan study` to print beside the
// virtual head's. "Proposed" is the paper's quasi-calibrated single-camera
// method, "SV" its phase-based stereo reference. mm unless said otherwise.
#pragma once

#include <array>

namespace cylscan::tools::paper {

// Section "Calibration": pose-wise residual RMSE of the 14 poses (Fig. 8b):
// 0.045–0.175 mm, median 0.075 mm; pooled RMSE (Eq. 12) 0.085 mm; S_eff
// from Section "Measurement uncertainty analysis".
inline constexpr double kCalibrationPoseRmseMin = 0.045;
inline constexpr double kCalibrationPoseRmseMax = 0.175;
inline constexpr double kCalibrationPoseRmseMedian = 0.075;
inline constexpr double kPooledRmse = 0.085;
inline constexpr double kSensitivityMmPerRad = 39.304;
inline constexpr int kCalibrationPoses = 14;

// Table "Reproducibility results for planar surface reconstruction" (10 poses).
inline constexpr std::array<double, 10> kPlaneReproProposed = {0.049, 0.061, 0.048, 0.061, 0.039,
                                                               0.086, 0.067, 0.081, 0.055, 0.076};
inline constexpr std::array<double, 10> kPlaneReproSv = {0.047, 0.051, 0.052, 0.054, 0.055,
                                                         0.055, 0.058, 0.065, 0.063, 0.066};

// Table "Repeatability results for planar surface reconstruction": RMSE of
// 5 repetitions at 2 fixed poses, [pose][repetition].
inline constexpr std::array<std::array<double, 5>, 2> kPlaneRepeatProposed = {
    {{0.073, 0.082, 0.085, 0.078, 0.083}, {0.050, 0.058, 0.056, 0.063, 0.068}}};
inline constexpr std::array<std::array<double, 5>, 2> kPlaneRepeatSv = {
    {{0.044, 0.043, 0.044, 0.043, 0.042}, {0.044, 0.043, 0.044, 0.042, 0.042}}};

// Table "Reproducibility results for spherical surface reconstruction"
// (10 poses): free-fit radius, and RMSE, signed mean, STD against R = 50.
struct SphereRow {
  double radius, rmse, mean, std;
};
inline constexpr std::array<SphereRow, 10> kSphereReproProposed = {
    {{49.994, 0.303, -0.003, 0.303},
     {49.914, 0.321, -0.102, 0.304},
     {50.025, 0.307, 0.036, 0.305},
     {49.950, 0.407, -0.056, 0.403},
     {50.119, 0.398, 0.152, 0.368},
     {50.000, 0.357, 0.003, 0.357},
     {50.022, 0.425, 0.033, 0.424},
     {49.939, 0.327, -0.069, 0.320},
     {49.942, 0.331, -0.067, 0.324},
     {49.988, 0.282, -0.012, 0.282}}};
inline constexpr std::array<SphereRow, 10> kSphereReproSv = {{{49.880, 0.181, -0.146, 0.107},
                                                              {49.802, 0.256, -0.236, 0.098},
                                                              {49.862, 0.205, -0.175, 0.108},
                                                              {49.812, 0.252, -0.227, 0.110},
                                                              {49.860, 0.212, -0.175, 0.121},
                                                              {49.875, 0.181, -0.152, 0.099},
                                                              {49.832, 0.235, -0.205, 0.114},
                                                              {49.803, 0.248, -0.229, 0.093},
                                                              {49.825, 0.227, -0.206, 0.095},
                                                              {49.846, 0.196, -0.178, 0.081}}};

// Table "Repeatability results for spherical surface reconstruction":
// 5 repetitions at 2 poses, [pose][repetition] (radius, RMSE, mean; no STD).
struct RepeatRow {
  double radius, rmse, mean;
};
inline constexpr std::array<std::array<RepeatRow, 5>, 2> kSphereRepeatProposed = {{
    {{{50.161, 0.438, 0.202},
      {50.185, 0.454, 0.231},
      {50.126, 0.416, 0.159},
      {50.199, 0.463, 0.248},
      {50.177, 0.448, 0.221}}},
    {{{49.955, 0.375, -0.049},
      {50.013, 0.394, 0.021},
      {49.986, 0.393, -0.011},
      {49.969, 0.378, -0.033},
      {49.959, 0.391, -0.044}}},
}};
inline constexpr std::array<std::array<RepeatRow, 5>, 2> kSphereRepeatSv = {{
    {{{49.784, 0.281, -0.258},
      {49.784, 0.280, -0.258},
      {49.747, 0.320, -0.302},
      {49.771, 0.295, -0.274},
      {49.758, 0.310, -0.289}}},
    {{{49.736, 0.334, -0.315},
      {49.767, 0.300, -0.277},
      {49.772, 0.295, -0.273},
      {49.767, 0.299, -0.278},
      {49.746, 0.323, -0.303}}},
}};

// Table "Summary of the uncertainty budget" and the text around it.
inline constexpr double kRepeatabilityStd = 0.018;         // largest STD of the sphere RMSE
inline constexpr double kReproducibilityStd = 0.049;       // STD of the pose-wise sphere RMSE
inline constexpr double kSphereDiameterTolerance = 0.051;  // Grade 2 acetal ball, ±
inline constexpr double kStageResolutionDeg = 0.004;       // DPIN LSR-100L
inline constexpr double kPeriodHighDeg = 5.0;
inline constexpr double kURep = 0.008, kURepr = 0.015, kURef = 0.029, kUCal = 0.085,
                        kUStage = 0.057, kCombined = 0.108, kExpanded = 0.215;
inline constexpr double kEffectiveDepthResolution = 0.198;

// Table "Regional RMSE comparison along the u-axis" (plane reproducibility).
inline constexpr double kRegionalCentral = 0.060, kRegionalOuter = 0.071;

}  // namespace cylscan::tools::paper
