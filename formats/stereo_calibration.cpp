// SPDX-License-Identifier: Apache-2.0
#include "formats/stereo_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/rotation.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kMaxFileBytes = 1u << 20;

struct NodeFault {
  std::string node;
  std::string fault;
};

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

template <int M, int N>
bool allFinite(const cv::Matx<double, M, N>& m) {
  for (int i = 0; i < M * N; ++i) {
    if (!std::isfinite(m.val[i])) return false;
  }
  return true;
}

std::optional<NodeFault> cameraMatrixFault(const std::string& node, const cv::Matx33d& k) {
  if (!allFinite(k)) return NodeFault{node, "contains a value that is not finite"};
  if (!(k(0, 0) > 0) || !(k(1, 1) > 0)) {
    return NodeFault{node, "focal lengths fx = " + number(k(0, 0)) + ", fy = " + number(k(1, 1)) +
                               " must be > 0"};
  }
  if (k(1, 0) != 0 || k(2, 0) != 0 || k(2, 1) != 0 || k(2, 2) != 1) {
    return NodeFault{node, "is not a camera matrix [fx s cx; 0 fy cy; 0 0 1]"};
  }
  return std::nullopt;
}

// The rules of a valid calibration, shared by the reader and the writer.
std::optional<NodeFault> calibrationFault(const StereoCalibration& c) {
  if (c.image_width <= 0) return NodeFault{"image_width", "must be > 0"};
  if (c.image_height <= 0) return NodeFault{"image_height", "must be > 0"};
  if (auto fault = cameraMatrixFault("camera_matrix_main", c.camera_matrix_main)) return fault;
  if (auto fault = cameraMatrixFault("camera_matrix_aux", c.camera_matrix_aux)) return fault;
  if (!allFinite(cv::Matx<double, 5, 1>(c.dist_coeffs_main.val))) {
    return NodeFault{"dist_coeffs_main", "contains a value that is not finite"};
  }
  if (!allFinite(cv::Matx<double, 5, 1>(c.dist_coeffs_aux.val))) {
    return NodeFault{"dist_coeffs_aux", "contains a value that is not finite"};
  }
  if (!allFinite(c.R)) return NodeFault{"R", "contains a value that is not finite"};
  if (auto fault = rotationFault(c.R)) return NodeFault{"R", *fault};
  if (!allFinite(cv::Matx31d(c.T.val)))
    return NodeFault{"T", "contains a value that is not finite"};
  return std::nullopt;
}

// Reads the nodes of an open FileStorage, InputError naming the file and node.
class CalibrationNodeReader {
 public:
  CalibrationNodeReader(const cv::FileStorage& storage, fs::path file)
      : storage_(storage), file_(std::move(file)) {}

  int integer(const std::string& name) const {
    const cv::FileNode node = find(name);
    if (!node.isInt()) fail(name, "must be an integer");
    return static_cast<int>(node);
  }

  // A rows×cols matrix; with `transposed_ok` the cols×rows one is accepted too.
  cv::Mat matrix(const std::string& name, int rows, int cols, bool transposed_ok) const {
    const cv::FileNode node = find(name);
    // Shape checks before OpenCV reads the matrix: it allocates rows x cols first.
    if (!node.isMap() || !node["rows"].isInt() || !node["cols"].isInt() || !node["data"].isSeq()) {
      fail(name, "is not an OpenCV matrix (!!opencv-matrix with rows, cols, dt, data)");
    }
    const int node_rows = static_cast<int>(node["rows"]);
    const int node_cols = static_cast<int>(node["cols"]);
    const bool size_ok = (node_rows == rows && node_cols == cols) ||
                         (transposed_ok && node_rows == cols && node_cols == rows);
    if (!size_ok) {
      fail(name, "is " + std::to_string(node_rows) + "x" + std::to_string(node_cols) +
                     ", expected " + std::to_string(rows) + "x" + std::to_string(cols));
    }
    const std::size_t expected_values =
        static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
    if (node["data"].size() != expected_values) {
      fail(name, "has " + std::to_string(node["data"].size()) + " values in \"data\", expected " +
                     std::to_string(rows * cols));
    }
    cv::Mat m;
    try {
      node >> m;
    } catch (const cv::Exception&) {
      m.release();
    }
    if (m.empty() || m.dims != 2 || m.total() != expected_values) {
      fail(name, "is not an OpenCV matrix (!!opencv-matrix with rows, cols, dt, data)");
    }
    if (m.channels() != 1) {
      fail(name, "must have 1 channel, it has " + std::to_string(m.channels()));
    }
    cv::Mat values;
    m.convertTo(values, CV_64F);
    values = values.reshape(1, rows);  // a transposed vector to the expected shape
    if (!cv::checkRange(values, true)) {
      fail(name, "contains a value that is not finite");
    }
    return values;
  }

  [[noreturn]] void fail(const std::string& node, const std::string& fault) const {
    throw InputError(file_, "node \"" + node + "\" " + fault);
  }

 private:
  cv::FileNode find(const std::string& name) const {
    const cv::FileNode node = storage_[name];
    if (node.empty() || node.isNone()) fail(name, "is missing");
    return node;
  }

  const cv::FileStorage& storage_;
  fs::path file_;
};

template <int M, int N>
cv::Matx<double, M, N> toMatx(const cv::Mat& m) {
  cv::Matx<double, M, N> out;
  for (int i = 0; i < M; ++i) {
    for (int j = 0; j < N; ++j)
      out(i, j) = m.at<double>(i, j);
  }
  return out;
}

template <int N>
cv::Vec<double, N> toVec(const cv::Mat& m) {
  cv::Vec<double, N> out;
  for (int i = 0; i < N; ++i)
    out[i] = m.ptr<double>()[i];  // continuous after convertTo
  return out;
}

// OpenCV 4.6's YAML parser never returns when the text after its first
// document begins with '-' but not "---". It gets there after a top-level
// collection that ends before the end of the file: one that begins on the
// "---" line or indented, or one ended by "...". The file is one map of
// named nodes, so its lines must look so before the parser sees them: the
// %YAML line, at most one "---" line of its own before the nodes, and a node
// name at the start of every line that does not begin with a space (blank
// lines and # comments aside). Then the top-level map ends only at the end.
void requireOneYamlMap(const std::string& text, const fs::path& file) {
  bool marker = false;
  bool nodes = false;
  int line = 0;
  for (std::size_t pos = 0; pos < text.size();) {
    ++line;
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view l(text.data() + pos, end - pos);
    pos = end + 1;
    while (!l.empty() && (l.back() == '\r' || l.back() == ' '))
      l.remove_suffix(1);
    if (line == 1 || l.empty() || l.front() == '#') continue;
    const auto fault = [&](const std::string& what) {
      throw InputError(file, "line " + std::to_string(line) + ": " + what);
    };
    const char c = l.front();
    if (l.starts_with("---")) {
      if (marker || nodes || l != "---")
        fault(
            "a YAML document marker other than one \"---\" line before the nodes (the file "
            "is one document)");
      marker = true;
    } else if (l.starts_with("...")) {
      fault("a YAML document end marker (the file is one document)");
    } else if (c == ' ') {
      if (!nodes) fault("the first node must begin at the start of its line");
    } else if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_') {
      nodes = true;
    } else if (c == '-') {
      fault("the top level is not a map of named nodes");
    } else {
      fault("a node name (a letter or '_') must begin every line that does not begin with a space");
    }
  }
}

}  // namespace

StereoCalibration readStereoCalibration(const fs::path& file) {
  const std::string text = readFileContents(file, kMaxFileBytes);
  if (text.empty()) throw InputError(file, "is empty, expected an OpenCV FileStorage YAML file");
  if (text.rfind("%YAML", 0) != 0 && text.rfind("<?xml", 0) != 0 && text.rfind('{', 0) != 0) {
    throw InputError(file,
                     "not an OpenCV FileStorage YAML file (it does not start with \"%YAML\")");
  }
  if (text.rfind("%YAML", 0) == 0) requireOneYamlMap(text, file);
  cv::FileStorage storage;
  try {
    storage.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  } catch (const cv::Exception& e) {
    // OpenCV 4.6's parser puts the line and reason into `func` and the parser's name into `err`.
    std::string detail = e.err + (e.func.empty() ? "" : " " + e.func);
    while (!detail.empty() && (detail.back() == '\n' || detail.back() == ' '))
      detail.pop_back();
    throw InputError(file, "not a valid OpenCV FileStorage YAML file (" + detail + ")");
  } catch (const std::exception& e) {
    // Some faults escape OpenCV's parser as std::length_error and the like.
    throw InputError(file,
                     std::string("not a valid OpenCV FileStorage YAML file (") + e.what() + ")");
  }
  if (!storage.isOpened()) throw InputError(file, "not a valid OpenCV FileStorage YAML file");

  if (!storage.root().isMap()) {
    throw InputError(file, "the top level is not a map of named nodes");
  }
  const CalibrationNodeReader nodes(storage, file);
  StereoCalibration c;
  try {
    c.image_width = nodes.integer("image_width");
    c.image_height = nodes.integer("image_height");
    c.camera_matrix_main = toMatx<3, 3>(nodes.matrix("camera_matrix_main", 3, 3, false));
    c.dist_coeffs_main = toVec<5>(nodes.matrix("dist_coeffs_main", 1, 5, true));
    c.camera_matrix_aux = toMatx<3, 3>(nodes.matrix("camera_matrix_aux", 3, 3, false));
    c.dist_coeffs_aux = toVec<5>(nodes.matrix("dist_coeffs_aux", 1, 5, true));
    c.R = toMatx<3, 3>(nodes.matrix("R", 3, 3, false));
    c.T = toVec<3>(nodes.matrix("T", 3, 1, true));
  } catch (const cv::Exception& e) {  // a structure the checks above did not foresee
    throw InputError(file, "malformed OpenCV FileStorage file (" + e.err + ")");
  }
  if (auto fault = calibrationFault(c)) nodes.fail(fault->node, fault->fault);
  return c;
}

void writeStereoCalibration(const fs::path& file, const StereoCalibration& calib) {
  if (auto fault = calibrationFault(calib)) {
    throw std::invalid_argument("stereo calibration " + file.string() + ": " + fault->node + " " +
                                fault->fault);
  }
  std::string text;
  try {
    cv::FileStorage storage(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    storage << "image_width" << calib.image_width;
    storage << "image_height" << calib.image_height;
    storage << "camera_matrix_main" << cv::Mat(calib.camera_matrix_main);
    storage << "dist_coeffs_main" << cv::Mat(calib.dist_coeffs_main).reshape(1, 1);
    storage << "camera_matrix_aux" << cv::Mat(calib.camera_matrix_aux);
    storage << "dist_coeffs_aux" << cv::Mat(calib.dist_coeffs_aux).reshape(1, 1);
    storage << "R" << cv::Mat(calib.R);
    storage << "T" << cv::Mat(calib.T);
    text = storage.releaseAndGetString();
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot encode stereo calibration " + file.string() + ": " + e.err);
  }
  writeFileAtomically(file, text);
}

}  // namespace cylscan::formats
