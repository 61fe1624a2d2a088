// SPDX-License-Identifier: Apache-2.0
#include "algo/quasi_calibration.hpp"

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "algo/numbers.hpp"

namespace cylscan::algo {
namespace {

// ------------------------------------------------------------------ layout
//
// offset size  field (all little-endian)
//      0    8  magic "CYLQCAL1"
//      8    4  u32 version (2; 1 is read too)
//     12    4  u32 header bytes (72; 64 in version 1)
//     16    4  u32 width
//     20    4  u32 height
//     24    4  u32 model id (3 = cubic)
//     28    4  u32 phase source (0 high, 1 fused)
//     32    4  u32 record bytes (56)
//     36    4  u32 pose count
//     40    4  u32 min poses
//     44    4  u32 valid pixel count
//     48    4  f32 pooled RMSE (mm, NaN if unknown)
//     52    4  f32 S_eff (mm/rad, NaN if unknown)
//     56    4  u32 payload bytes
//     60    4  u32 CRC-32 (IEEE, reflected 0xEDB88320) of bytes [0, 60) and of
//              everything from byte 64 on
//     64    4  f32 order-residual centre the poses were unwrapped about (rad, NaN
//              if unknown; version 2 only)
//     68    4  f32 the poses' order-residual spread (rad, NaN if unknown; version 2)
//     72       payload (at 64 in version 1): width·height validity bytes (0/1), zero padding to a
//              multiple of 4, then width·height PixelPolynomial records
//              (14 f32: Φc, g, x0..x3, y0..y3, z0..z3), row-major.
constexpr char kMagic[8] = {'C', 'Y', 'L', 'Q', 'C', 'A', 'L', '1'};
constexpr std::uint32_t kVersion = 2;
constexpr std::size_t kHeaderBytes = 72;
constexpr std::size_t kHeaderBytesV1 = 64;
constexpr std::uint32_t kCubicModel = 3;
constexpr std::size_t kRecordBytes = sizeof(PixelPolynomial);
constexpr std::size_t kCrcOffset = 60;
constexpr int kMaxSide = 16384;
constexpr std::size_t kMaxPixels = std::size_t{1} << 25;

constexpr std::array<std::uint32_t, 256> makeCrcTable() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k)
      c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = makeCrcTable();

std::uint32_t crc32Update(std::uint32_t crc, std::span<const std::byte> bytes) {
  for (std::byte b : bytes)
    crc = kCrcTable[(crc ^ std::to_integer<std::uint32_t>(b)) & 0xffu] ^ (crc >> 8);
  return crc;
}

std::uint32_t fileCrc(std::span<const std::byte> file) {
  std::uint32_t crc = 0xffffffffu;
  crc = crc32Update(crc, file.first(kCrcOffset));
  crc = crc32Update(crc, file.subspan(kHeaderBytesV1));
  return crc ^ 0xffffffffu;
}

std::size_t paddedValidityBytes(std::size_t pixels) {
  return (pixels + 3) / 4 * 4;
}

void putU32(std::byte* at, std::uint32_t value) {
  for (int i = 0; i < 4; ++i)
    at[i] = static_cast<std::byte>((value >> (8 * i)) & 0xffu);
}
void putF32(std::byte* at, float value) {
  putU32(at, std::bit_cast<std::uint32_t>(value));
}
std::uint32_t getU32(const std::byte* at) {
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i)
    value |= std::to_integer<std::uint32_t>(at[i]) << (8 * i);
  return value;
}
float getF32(const std::byte* at) {
  return std::bit_cast<float>(getU32(at));
}

[[noreturn]] void fault(const std::string& what) {
  throw std::invalid_argument("quasi-calibration: " + what);
}

struct ParsedHeader {
  cv::Size size;
  QuasiCalibrationInfo info;
  std::size_t valid_count = 0;
  std::size_t header_bytes = 0;  // where the validity plane starts
  std::size_t records_offset = 0;
};

// Every check of a serialised calibration, in the order that names the most
// specific fault first. Does not look at the validity plane's values.
ParsedHeader parseHeader(std::span<const std::byte> bytes) {
  if (bytes.size() < kHeaderBytesV1)
    fault("truncated: " + std::to_string(bytes.size()) + " bytes, shorter than the 64-byte header");
  if (std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    fault("bad magic (not a CYLQCAL1 calibration)");
  const std::byte* h = bytes.data();
  const std::uint32_t version = getU32(h + 8);
  if (version != kVersion && version != 1) fault("unsupported version " + std::to_string(version));
  const std::size_t header_bytes = version == 1 ? kHeaderBytesV1 : kHeaderBytes;
  if (getU32(h + 12) != header_bytes || getU32(h + 32) != kRecordBytes)
    fault("unsupported layout (header or record size)");
  if (bytes.size() < header_bytes)
    fault("truncated: " + std::to_string(bytes.size()) + " bytes, shorter than the " +
          std::to_string(header_bytes) + "-byte header");
  const std::uint32_t model = getU32(h + 24);
  if (model != kCubicModel) fault("unknown model id " + std::to_string(model));
  const std::uint32_t source = getU32(h + 28);
  if (source > 1) fault("unknown phase source " + std::to_string(source));
  const std::uint32_t width = getU32(h + 16);
  const std::uint32_t height = getU32(h + 20);
  if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide ||
      std::size_t{width} * height > kMaxPixels)
    fault("absurd image size " + std::to_string(width) + "x" + std::to_string(height));
  const std::size_t pixels = std::size_t{width} * height;
  const std::size_t payload = paddedValidityBytes(pixels) + pixels * kRecordBytes;
  if (getU32(h + 56) != payload) fault("payload size does not match the image size");
  if (bytes.size() < header_bytes + payload)
    fault("truncated: " + std::to_string(bytes.size()) + " bytes, expected " +
          std::to_string(header_bytes + payload));
  if (bytes.size() > header_bytes + payload)
    fault("trailing bytes: " + std::to_string(bytes.size()) + " bytes, expected " +
          std::to_string(header_bytes + payload));
  if (fileCrc(bytes) != getU32(h + kCrcOffset)) fault("checksum mismatch (corrupt data)");

  ParsedHeader out;
  out.size = cv::Size(static_cast<int>(width), static_cast<int>(height));
  out.info.phase_source = static_cast<PhaseSource>(source);
  out.info.pose_count = getU32(h + 36);
  out.info.min_poses = getU32(h + 40);
  out.valid_count = getU32(h + 44);
  out.info.pooled_rmse_mm = getF32(h + 48);
  out.info.sensitivity_mm_per_rad = getF32(h + 52);
  if (version >= 2) {
    out.info.order_centre_rad = getF32(h + 64);
    out.info.order_spread_rad = getF32(h + 68);
  }
  out.header_bytes = header_bytes;
  out.records_offset = header_bytes + paddedValidityBytes(pixels);
  return out;
}

void checkValidityPlane(const ParsedHeader& header, const std::uint8_t* valid) {
  std::size_t count = 0;
  const std::size_t pixels = static_cast<std::size_t>(header.size.area());
  for (std::size_t i = 0; i < pixels; ++i) {
    if (valid[i] > 1) fault("corrupt validity plane");
    count += valid[i];
  }
  if (count != header.valid_count) fault("valid pixel count does not match the validity plane");
}

// Horner in float, one fixed order: ((c3·t + c2)·t + c1)·t + c0.
inline float horner(const float c[4], float t) {
  return ((c[3] * t + c[2]) * t + c[1]) * t + c[0];
}

// The normalised phase, or NaN when phi is NaN or beyond the limit.
inline float normalisedPhase(const PixelPolynomial& p, float phi, float limit) {
  const float t = (phi - p.phase_centre) * p.phase_inv_half;
  return std::abs(t) <= limit ? t : kNaNf;
}

}  // namespace

// ------------------------------------------------------------------ view

QuasiCalibrationView::QuasiCalibrationView(cv::Size size, const std::uint8_t* valid,
                                           const PixelPolynomial* pixels, QuasiCalibrationInfo info)
    : size_(size), valid_(valid), pixels_(pixels), info_(info) {}

QuasiCalibrationView QuasiCalibrationView::fromBytes(std::span<const std::byte> bytes) {
  if constexpr (std::endian::native != std::endian::little) {
    fault("in-place use needs a little-endian host; use deserialize()");
  }
  const ParsedHeader header = parseHeader(bytes);
  if (reinterpret_cast<std::uintptr_t>(bytes.data()) % alignof(PixelPolynomial) != 0)
    fault("in-place use needs 4-byte aligned bytes");
  const auto* valid = reinterpret_cast<const std::uint8_t*>(bytes.data() + header.header_bytes);
  checkValidityPlane(header, valid);
  const auto* pixels =
      reinterpret_cast<const PixelPolynomial*>(bytes.data() + header.records_offset);
  return QuasiCalibrationView(header.size, valid, pixels, header.info);
}

std::size_t QuasiCalibrationView::validCount() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(size_.area()); ++i)
    n += valid_[i] != 0;
  return n;
}

cv::Vec3f QuasiCalibrationView::evaluate(int u, int v, float phi) const {
  const std::size_t i = index(u, v);
  if (!valid_[i]) return cv::Vec3f(kNaNf, kNaNf, kNaNf);
  const PixelPolynomial& p = pixels_[i];
  const float t = normalisedPhase(p, phi, limit_);
  if (std::isnan(t)) return cv::Vec3f(kNaNf, kNaNf, kNaNf);
  return cv::Vec3f(horner(p.x, t), horner(p.y, t), horner(p.z, t));
}

float QuasiCalibrationView::evaluateDepth(int u, int v, float phi) const {
  const std::size_t i = index(u, v);
  if (!valid_[i]) return kNaNf;
  const PixelPolynomial& p = pixels_[i];
  const float t = normalisedPhase(p, phi, limit_);
  return std::isnan(t) ? kNaNf : horner(p.z, t);
}

void QuasiCalibrationView::checkPhase(const cv::Mat& phase) const {
  if (phase.type() != CV_32FC1 || phase.size() != size_)
    throw std::invalid_argument("quasi-calibration: the phase map must be CV_32F of " +
                                std::to_string(size_.width) + "x" + std::to_string(size_.height));
}

cv::Mat QuasiCalibrationView::evaluate(const cv::Mat& phase) const {
  checkPhase(phase);
  cv::Mat out(size_, CV_32FC3);
  for (int v = 0; v < size_.height; ++v) {
    const float* phi = phase.ptr<float>(v);
    auto* dst = out.ptr<cv::Vec3f>(v);
    for (int u = 0; u < size_.width; ++u)
      dst[u] = evaluate(u, v, phi[u]);
  }
  return out;
}

cv::Mat QuasiCalibrationView::evaluateDepth(const cv::Mat& phase) const {
  checkPhase(phase);
  cv::Mat out(size_, CV_32FC1);
  for (int v = 0; v < size_.height; ++v) {
    const float* phi = phase.ptr<float>(v);
    float* dst = out.ptr<float>(v);
    for (int u = 0; u < size_.width; ++u)
      dst[u] = evaluateDepth(u, v, phi[u]);
  }
  return out;
}

double QuasiCalibrationView::depthSlope(int u, int v, double phi) const {
  const std::size_t i = index(u, v);
  if (!valid_[i]) return kNaN;
  const PixelPolynomial& p = pixels_[i];
  const double g = p.phase_inv_half;
  const double t = (phi - p.phase_centre) * g;
  if (!(std::abs(t) <= limit_)) return kNaN;
  return ((3.0 * p.z[3] * t + 2.0 * p.z[2]) * t + p.z[1]) * g;
}

// ------------------------------------------------------------------ value

QuasiCalibration::QuasiCalibration(cv::Size size, std::vector<std::uint8_t> valid,
                                   std::vector<PixelPolynomial> pixels, QuasiCalibrationInfo info)
    : size_(size), valid_(std::move(valid)), pixels_(std::move(pixels)), info_(info) {
  const auto n = static_cast<std::size_t>(size_.area());
  if (size_.width <= 0 || size_.height <= 0 || valid_.size() != n || pixels_.size() != n)
    throw std::invalid_argument("quasi-calibration: arrays do not match the image size");
}

void QuasiCalibration::setResidualSummary(float pooled_rmse_mm, float sensitivity_mm_per_rad) {
  info_.pooled_rmse_mm = pooled_rmse_mm;
  info_.sensitivity_mm_per_rad = sensitivity_mm_per_rad;
}

void QuasiCalibration::setOrderResidual(float centre_rad, float spread_rad) {
  info_.order_centre_rad = centre_rad;
  info_.order_spread_rad = spread_rad;
}

QuasiCalibrationView QuasiCalibration::view() const {
  QuasiCalibrationView view(size_, valid_.data(), pixels_.data(), info_);
  view.setExtrapolationLimit(limit_);
  return view;
}

std::vector<std::byte> QuasiCalibration::serialize() const {
  const std::size_t pixels = valid_.size();
  const std::size_t validity = paddedValidityBytes(pixels);
  const std::size_t payload = validity + pixels * kRecordBytes;
  std::vector<std::byte> out(kHeaderBytes + payload, std::byte{0});
  std::byte* h = out.data();
  std::memcpy(h, kMagic, sizeof kMagic);
  putU32(h + 8, kVersion);
  putU32(h + 12, kHeaderBytes);
  putU32(h + 16, static_cast<std::uint32_t>(size_.width));
  putU32(h + 20, static_cast<std::uint32_t>(size_.height));
  putU32(h + 24, kCubicModel);
  putU32(h + 28, static_cast<std::uint32_t>(info_.phase_source));
  putU32(h + 32, kRecordBytes);
  putU32(h + 36, info_.pose_count);
  putU32(h + 40, info_.min_poses);
  putU32(h + 44, static_cast<std::uint32_t>(validCount()));
  putF32(h + 48, info_.pooled_rmse_mm);
  putF32(h + 52, info_.sensitivity_mm_per_rad);
  putU32(h + 56, static_cast<std::uint32_t>(payload));
  putF32(h + 64, info_.order_centre_rad);
  putF32(h + 68, info_.order_spread_rad);
  for (std::size_t i = 0; i < pixels; ++i)
    h[kHeaderBytes + i] = static_cast<std::byte>(valid_[i] ? 1 : 0);
  std::byte* record = h + kHeaderBytes + validity;
  for (const PixelPolynomial& p : pixels_) {
    const float values[14] = {p.phase_centre, p.phase_inv_half, p.x[0], p.x[1], p.x[2],
                              p.x[3],         p.y[0],           p.y[1], p.y[2], p.y[3],
                              p.z[0],         p.z[1],           p.z[2], p.z[3]};
    for (float value : values) {
      putF32(record, value);
      record += 4;
    }
  }
  putU32(h + kCrcOffset, fileCrc(out));
  return out;
}

QuasiCalibration QuasiCalibration::deserialize(std::span<const std::byte> bytes) {
  const ParsedHeader header = parseHeader(bytes);
  const std::size_t pixels = static_cast<std::size_t>(header.size.area());
  std::vector<std::uint8_t> valid(pixels);
  for (std::size_t i = 0; i < pixels; ++i)
    valid[i] = std::to_integer<std::uint8_t>(bytes[header.header_bytes + i]);
  checkValidityPlane(header, valid.data());
  std::vector<PixelPolynomial> records(pixels);
  const std::byte* at = bytes.data() + header.records_offset;
  for (PixelPolynomial& p : records) {
    float values[14];
    for (float& value : values) {
      value = getF32(at);
      at += 4;
    }
    p.phase_centre = values[0];
    p.phase_inv_half = values[1];
    for (int k = 0; k < 4; ++k) {
      p.x[k] = values[2 + k];
      p.y[k] = values[6 + k];
      p.z[k] = values[10 + k];
    }
  }
  return QuasiCalibration(header.size, std::move(valid), std::move(records), header.info);
}

void QuasiCalibration::requireImageSize(cv::Size expected) const {
  if (expected != size_)
    throw std::invalid_argument("quasi-calibration: made for " + std::to_string(size_.width) + "x" +
                                std::to_string(size_.height) + " images, but the images are " +
                                std::to_string(expected.width) + "x" +
                                std::to_string(expected.height));
}

// ------------------------------------------------------------------ fitting

QuasiCalibrationFitter::QuasiCalibrationFitter(cv::Size size, QuasiCalibrationOptions options)
    : size_(size), options_(options) {
  if (size.width <= 0 || size.height <= 0)
    throw std::invalid_argument("quasi-calibration fitter: empty image size");
  if (options.min_poses <= 4)
    throw std::invalid_argument("quasi-calibration fitter: min_poses must be > 4 for a cubic");
  if (!(options.min_phase_range_rad > 0.0))
    throw std::invalid_argument("quasi-calibration fitter: min_phase_range_rad must be > 0");
  pixels_.resize(static_cast<std::size_t>(size.area()));
}

void QuasiCalibrationFitter::addPose(const cv::Mat& phase, const cv::Mat& target_xyz) {
  if (phase.type() != CV_32FC1 || phase.size() != size_ || target_xyz.type() != CV_32FC3 ||
      target_xyz.size() != size_)
    throw std::invalid_argument(
        "quasi-calibration fitter: a pose needs a CV_32F phase and a CV_32FC3 target of the "
        "calibration's image size");
  for (int v = 0; v < size_.height; ++v) {
    const float* phi = phase.ptr<float>(v);
    const auto* xyz = target_xyz.ptr<cv::Vec3f>(v);
    Accumulator* acc = pixels_.data() + static_cast<std::size_t>(v) * size_.width;
    for (int u = 0; u < size_.width; ++u) {
      const cv::Vec3f& p = xyz[u];
      if (!std::isfinite(phi[u]) || !std::isfinite(p[0]) || !std::isfinite(p[1]) ||
          !std::isfinite(p[2]))
        continue;
      Accumulator& a = acc[u];
      const double f = phi[u];
      if (a.count == 0) a.first_phase = a.min_phase = a.max_phase = f;
      a.min_phase = std::min(a.min_phase, f);
      a.max_phase = std::max(a.max_phase, f);
      const double s = f - a.first_phase;
      double power = 1.0;
      for (int k = 0; k < 7; ++k) {
        a.phase_moments[k] += power;
        if (k < 4)
          for (int c = 0; c < 3; ++c)
            a.xyz_moments[c][k] += power * static_cast<double>(p[c]);
        power *= s;
      }
      ++a.count;
    }
  }
  ++pose_count_;
}

QuasiCalibration QuasiCalibrationFitter::fit() const {
  const std::size_t n = pixels_.size();
  std::vector<std::uint8_t> valid(n, 0);
  std::vector<PixelPolynomial> records(n);
  constexpr double kBinomial[7][7] = {{1},
                                      {1, 1},
                                      {1, 2, 1},
                                      {1, 3, 3, 1},
                                      {1, 4, 6, 4, 1},
                                      {1, 5, 10, 10, 5, 1},
                                      {1, 6, 15, 20, 15, 6, 1}};
  for (std::size_t i = 0; i < n; ++i) {
    const Accumulator& a = pixels_[i];
    if (a.count < static_cast<std::uint32_t>(options_.min_poses)) continue;
    const double half = 0.5 * (a.max_phase - a.min_phase);
    if (!(2.0 * half >= options_.min_phase_range_rad)) continue;
    // The normalisation as the evaluation will see it (float), used exactly.
    const float centre = static_cast<float>(a.min_phase + half);
    const float inv_half = static_cast<float>(1.0 / half);
    const double g = inv_half;
    const double s0 = static_cast<double>(centre) - a.first_phase;  // t = (s − s0)·g

    // Moments in t from the moments in s: Σ t^k = g^k Σ_j C(k,j) (−s0)^(k−j) Σ s^j.
    double neg_s0_pow[7];
    double g_pow[7];
    neg_s0_pow[0] = g_pow[0] = 1.0;
    for (int k = 1; k < 7; ++k) {
      neg_s0_pow[k] = neg_s0_pow[k - 1] * -s0;
      g_pow[k] = g_pow[k - 1] * g;
    }
    double t_moments[7];
    double t_xyz[3][4];
    for (int k = 0; k < 7; ++k) {
      double sum = 0.0;
      for (int j = 0; j <= k; ++j)
        sum += kBinomial[k][j] * neg_s0_pow[k - j] * a.phase_moments[j];
      t_moments[k] = g_pow[k] * sum;
    }
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 4; ++k) {
        double sum = 0.0;
        for (int j = 0; j <= k; ++j)
          sum += kBinomial[k][j] * neg_s0_pow[k - j] * a.xyz_moments[c][j];
        t_xyz[c][k] = g_pow[k] * sum;
      }
    }
    Eigen::Matrix4d normal;
    Eigen::Matrix<double, 4, 3> rhs;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c)
        normal(r, c) = t_moments[r + c];
      for (int c = 0; c < 3; ++c)
        rhs(r, c) = t_xyz[c][r];
    }
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(normal);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) continue;
    const Eigen::Matrix<double, 4, 3> coefficients = ldlt.solve(rhs);
    if (!coefficients.allFinite()) continue;

    PixelPolynomial& p = records[i];
    p.phase_centre = centre;
    p.phase_inv_half = inv_half;
    for (int k = 0; k < 4; ++k) {
      p.x[k] = static_cast<float>(coefficients(k, 0));
      p.y[k] = static_cast<float>(coefficients(k, 1));
      p.z[k] = static_cast<float>(coefficients(k, 2));
    }
    valid[i] = 1;
  }
  QuasiCalibrationInfo info;
  info.phase_source = options_.phase_source;
  info.pose_count = static_cast<std::uint32_t>(pose_count_);
  info.min_poses = static_cast<std::uint32_t>(options_.min_poses);
  return QuasiCalibration(size_, std::move(valid), std::move(records), info);
}

// ------------------------------------------------------------------ residuals

void QuasiCalibrationResiduals::addPose(const cv::Mat& phase, const cv::Mat& target_xyz) {
  const cv::Size size = calibration_.size();
  if (phase.type() != CV_32FC1 || phase.size() != size || target_xyz.type() != CV_32FC3 ||
      target_xyz.size() != size)
    throw std::invalid_argument(
        "quasi-calibration residuals: a pose needs a CV_32F phase and a CV_32FC3 target of the "
        "calibration's image size");
  const QuasiCalibrationView view = calibration_.view();
  double depth = 0.0;
  double distance = 0.0;
  std::size_t count = 0;
  for (int v = 0; v < size.height; ++v) {
    const float* phi = phase.ptr<float>(v);
    const auto* target = target_xyz.ptr<cv::Vec3f>(v);
    for (int u = 0; u < size.width; ++u) {
      const cv::Vec3f& t = target[u];
      if (!std::isfinite(phi[u]) || !std::isfinite(t[0]) || !std::isfinite(t[1]) ||
          !std::isfinite(t[2]))
        continue;
      const cv::Vec3f p = view.evaluate(u, v, phi[u]);
      if (std::isnan(p[0])) continue;
      const double dx = static_cast<double>(p[0]) - t[0];
      const double dy = static_cast<double>(p[1]) - t[1];
      const double dz = static_cast<double>(p[2]) - t[2];
      depth += dz * dz;
      distance += dx * dx + dy * dy + dz * dz;
      slope_sum_ += std::abs(view.depthSlope(u, v, phi[u]));
      ++count;
    }
  }
  PoseResidual pose;
  pose.pixel_count = count;
  pose.depth_rmse_mm = count ? std::sqrt(depth / static_cast<double>(count)) : kNaN;
  pose.distance_rmse_mm = count ? std::sqrt(distance / static_cast<double>(count)) : kNaN;
  poses_.push_back(pose);
  depth_sum_ += depth;
  distance_sum_ += distance;
  count_ += count;
}

CalibrationResiduals QuasiCalibrationResiduals::result() const {
  CalibrationResiduals out;
  out.poses = poses_;
  out.pixel_count = count_;
  const double p = static_cast<double>(count_);
  out.pooled_depth_rmse_mm = count_ ? std::sqrt(depth_sum_ / p) : kNaN;
  out.pooled_distance_rmse_mm = count_ ? std::sqrt(distance_sum_ / p) : kNaN;
  out.sensitivity_mm_per_rad = count_ ? slope_sum_ / p : kNaN;
  return out;
}

}  // namespace cylscan::algo
