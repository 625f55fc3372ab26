// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/stereo/calibration_io.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

namespace planar_grid {

namespace {

/** \brief Largest image width or height accepted from a calibration file, pixels. */
constexpr double MAX_IMAGE_SIDE_PX = 10000.0;

/** \brief A 3x4 projection matrix, row-major. */
using ProjectionMatrix = std::array<double, 12>;

/** \brief Reads the 12 numbers of a projection row from \a row into \a p.
 * \param[out] non_finite the 1-based position of the first value that is not finite
 * ("nan", "inf", "infinity" in any case, or a number past the range of a double), 0
 * when every value is finite; \param[out] token that value as written
 * \return false when the row holds fewer than 12 values or one is not a number */
bool
readProjectionRow(std::istream& row,
                  ProjectionMatrix& p,
                  std::size_t& non_finite,
                  std::string& token)
{
  non_finite = 0;
  for (std::size_t k = 0; k < p.size(); ++k) {
    std::string value;
    if (!(row >> value))
      return false;
    std::istringstream number(value);
    char extra = 0;
    if ((number >> p[k]) && !(number >> extra) && std::isfinite(p[k]))
      continue;
    // The stream reads no "nan" or "inf" and fails on a number out of range; strtod
    // (the C locale's, as the stream's) reads them as the non-finite values they are.
    const char* begin = value.c_str();
    char* end = nullptr;
    p[k] = std::strtod(begin, &end);
    if (end != begin + value.size() || std::isfinite(p[k]))
      return false;
    if (non_finite == 0) {
      non_finite = k + 1;
      token = value;
    }
  }
  return true;
}

/** \brief Reads the 3x4 rows \a left_key and \a right_key ("P1_roi:") of a plain-text
 * calib.txt (one "key: 12 numbers" per line) into \a left and \a right. With
 * \a unlabelled_fallback, a file without either key whose lines are bare rows of 12
 * numbers (some KITTI odometry excerpts strip the "P0:" / "P1:" labels) gives its first
 * two such rows as \a left and \a right; a file mixing labelled and unlabelled rows,
 * or with fewer than two unlabelled rows, is an IOError. */
void
readTextProjectionRows(const std::string& path,
                       const std::string& left_key,
                       const std::string& right_key,
                       bool unlabelled_fallback,
                       ProjectionMatrix& left,
                       ProjectionMatrix& right,
                       int& right_line)
{
  std::ifstream file(path);
  if (!file)
    throw IOError(path + ": cannot open the calibration file");
  bool found_left = false;
  bool found_right = false;
  bool any_label = false;
  std::vector<ProjectionMatrix> unlabelled;
  std::vector<int> unlabelled_lines;
  int left_line = 0;
  int line_number = 0;
  std::string line;
  while (std::getline(file, line)) {
    ++line_number;
    std::istringstream row(line);
    std::string key;
    if (!(row >> key))
      continue;
    if (key != left_key && key != right_key) {
      // A bare row: exactly 12 numbers and nothing else.
      std::istringstream numbers(line);
      ProjectionMatrix p{};
      std::size_t non_finite = 0;
      std::string token;
      const bool complete = readProjectionRow(numbers, p, non_finite, token);
      std::string rest;
      if (complete && !(numbers >> rest)) {
        // Only a KITTI file reads its bare rows (a Karlsruhe file ignores them).
        if (non_finite > 0 && unlabelled_fallback)
          throw IOError(path + ":" + std::to_string(line_number) + ": value "
                        + std::to_string(non_finite) + " of the row, '" + token
                        + "', is not a finite number");
        unlabelled.push_back(p);
        unlabelled_lines.push_back(line_number);
      } else
        any_label = true;
      continue;
    }
    any_label = true;
    // A row given twice would silently take the later one.
    int& first_line = key == left_key ? left_line : right_line;
    if (first_line > 0)
      throw IOError(path + ":" + std::to_string(line_number) + ": row '" + key
                    + "' is given twice (first at line " + std::to_string(first_line)
                    + ")");
    first_line = line_number;
    ProjectionMatrix& p = (key == left_key) ? left : right;
    std::size_t non_finite = 0;
    std::string token;
    if (!readProjectionRow(row, p, non_finite, token))
      throw IOError(path + ":" + std::to_string(line_number) + ": row '" + key
                    + "' must hold 12 numbers (3x4, row-major)");
    if (non_finite > 0)
      throw IOError(path + ":" + std::to_string(line_number) + ": row '" + key
                    + "' value " + std::to_string(non_finite) + ", '" + token
                    + "', is not a finite number");
    (key == left_key ? found_left : found_right) = true;
  }
  if (unlabelled_fallback && !found_left && !found_right && !any_label) {
    if (unlabelled.size() < 2)
      throw IOError(path + ": no '" + left_key + "' / '" + right_key
                    + "' rows and fewer than two unlabelled rows of 12 numbers");
    left = unlabelled[0];
    right = unlabelled[1];
    right_line = unlabelled_lines[1];
    return;
  }
  if (!found_left)
    throw IOError(path + ": missing row '" + left_key + "'");
  if (!found_right)
    throw IOError(path + ": missing row '" + right_key + "'");
}

/** \brief Throws an IOError naming \a where (the row's file:line) when \a baseline_m
 * is a positive finite number outside StereoCalibration's [MIN_BASELINE_M,
 * MAX_BASELINE_M] (a wrong unit or a corrupt row, which would scale every depth);
 * other values, and the formats without rows, are left to
 * StereoCalibration::validate(). */
void
checkBaselineRange(const std::string& where, double baseline_m)
{
  using C = StereoCalibration;
  if (std::isfinite(baseline_m) && baseline_m > 0.0
      && (baseline_m < C::MIN_BASELINE_M || baseline_m > C::MAX_BASELINE_M)) {
    std::ostringstream text;
    text << where << ": the baseline is " << baseline_m << " m, outside ["
         << C::MIN_BASELINE_M << ", " << C::MAX_BASELINE_M
         << "] m for a stereo rig (a wrong unit or a corrupt value)";
    throw IOError(text.str());
  }
}

/** \brief Relative tolerance within which the right camera's focal lengths and
 * principal point must equal the left's in a rectified pair (0.06 px at f = 645 px):
 * the projections of a rectified pair share them, and a right camera that differs
 * gives every disparity an offset and the baseline (-P_r(0,3) / P_r(0,0)) a wrong
 * scale. */
constexpr double RECTIFIED_INTRINSICS_TOLERANCE = 1e-4;

/** \brief Throws an IOError naming \a where and the value when the right projection's
 * fx, fy, cx or cy differs from the left's by more than RECTIFIED_INTRINSICS_TOLERANCE
 * of the larger of the two (and of 1 px). A left focal length that is not positive is
 * left to StereoCalibration::validate(), which names it as such. */
void
checkRectifiedIntrinsics(const std::string& where,
                         const ProjectionMatrix& left,
                         const ProjectionMatrix& right)
{
  if (!(left[0] > 0.0))
    return;
  const std::pair<const char*, std::size_t> values[] = {
    {"focal length fx, P(0,0)", 0},
    {"focal length fy, P(1,1)", 5},
    {"principal point cx, P(0,2)", 2},
    {"principal point cy, P(1,2)", 6}};
  for (const auto& [name, at] : values) {
    const double l = left[at];
    const double r = right[at];
    const double scale = std::max({std::abs(l), std::abs(r), 1.0});
    if (!(std::abs(l - r) <= RECTIFIED_INTRINSICS_TOLERANCE * scale)) {
      std::ostringstream text;
      text.precision(10);
      text << where << ": the right camera's " << name << " is " << r
           << " px, the left camera's " << l
           << " px: the cameras of a rectified pair share their focal length and "
              "principal point (relative tolerance "
           << RECTIFIED_INTRINSICS_TOLERANCE
           << "), so the baseline and every depth would be wrong";
      throw IOError(text.str());
    }
  }
}

/** \brief Rectified intrinsics from the left and right 3x4 projection matrices of a
 * rectified pair: f = P_l(0,0), cx = P_l(0,2), cy = P_l(1,2), B = -P_r(0,3) / P_r(0,0).
 */
StereoCalibration
calibrationFromProjections(const ProjectionMatrix& left, const ProjectionMatrix& right)
{
  StereoCalibration calibration;
  calibration.focal_length_px = left[0];
  calibration.cx_px = left[2];
  calibration.cy_px = left[6];
  // P_r(0,0) == 0 gives a non-finite baseline, which validate() rejects.
  calibration.baseline_m = -right[3] / right[0];
  return calibration;
}

/** \brief yaml-cpp's LoadFile with the failure turned into an IOError naming the file.
 * \note OpenCV-written YAML (EuRoC, rtabmap) starts with "%YAML:1.0"; yaml-cpp 0.7
 *       treats it as an unknown directive and ignores it (checked on the shared data),
 *       so the file is loaded as is. */
YAML::Node
loadYamlFile(const std::string& path)
{
  {
    std::ifstream probe(path);
    if (!probe)
      throw IOError(path + ": cannot open the calibration file");
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw IOError(path + ": not valid YAML: " + e.what());
  }
  // The fields are looked up by name: a scalar or a list at the top has none (and
  // yaml-cpp throws on a lookup in a scalar).
  if (!root.IsMap())
    throw IOError(path + ": not a YAML map of calibration fields");
  return root;
}

/** \brief The child \a key of \a node, which must exist. */
YAML::Node
requireField(const YAML::Node& node, const std::string& key, const std::string& path)
{
  if (!node.IsMap() || !node[key])
    throw IOError(path + ": missing field '" + key + "'");
  // yaml-cpp keeps both entries of a key given twice and answers with one of them.
  int seen = 0;
  for (const auto& entry : node)
    if (entry.first.IsScalar() && entry.first.Scalar() == key && ++seen == 2)
      throw IOError(path + ":" + std::to_string(entry.first.Mark().line + 1)
                    + ": field '" + key + "' is given twice");
  return node[key];
}

/** \brief A scalar field converted to T. */
template <typename T>
T
readScalar(const YAML::Node& node, const std::string& key, const std::string& path)
{
  const YAML::Node value = requireField(node, key, path);
  try {
    return value.as<T>();
  } catch (const YAML::Exception&) {
    throw IOError(path + ": field '" + key + "' is not a valid number");
  }
}

/** \brief A sequence field of exactly \a count numbers. */
std::vector<double>
readNumbers(const YAML::Node& node,
            const std::string& key,
            std::size_t count,
            const std::string& path)
{
  const YAML::Node value = requireField(node, key, path);
  std::vector<double> numbers;
  try {
    numbers = value.as<std::vector<double>>();
  } catch (const YAML::Exception&) {
    throw IOError(path + ": field '" + key + "' must be a list of numbers");
  }
  if (numbers.size() != count)
    throw IOError(path + ": field '" + key + "' must hold " + std::to_string(count)
                  + " numbers, got " + std::to_string(numbers.size()));
  for (const double number : numbers)
    if (!std::isfinite(number))
      throw IOError(path + ": field '" + key + "' holds a non-finite number");
  return numbers;
}

/** \brief An OpenCV matrix node {rows, cols, data} of the given shape. */
std::vector<double>
readMatrix(const YAML::Node& node,
           const std::string& key,
           int rows,
           int cols,
           const std::string& path)
{
  const YAML::Node matrix = requireField(node, key, path);
  const int file_rows = readScalar<int>(matrix, "rows", path);
  const int file_cols = readScalar<int>(matrix, "cols", path);
  if (file_rows != rows || file_cols != cols)
    throw IOError(path + ": field '" + key + "' must be " + std::to_string(rows) + "x"
                  + std::to_string(cols) + ", got " + std::to_string(file_rows) + "x"
                  + std::to_string(file_cols));
  return readNumbers(matrix, "data", static_cast<std::size_t>(rows * cols), path);
}

StereoCameraModel
loadTextCalibration(const std::string& path,
                    const std::string& left_key,
                    const std::string& right_key,
                    bool unlabelled_fallback)
{
  ProjectionMatrix left{}, right{};
  int right_line = 0;
  readTextProjectionRows(path, left_key, right_key, unlabelled_fallback, left, right,
                         right_line);
  checkRectifiedIntrinsics(path + ":" + std::to_string(right_line), left, right);
  StereoCameraModel model;
  model.calibration = calibrationFromProjections(left, right);
  checkBaselineRange(path + ":" + std::to_string(right_line),
                     model.calibration.baseline_m);
  return model;
}

StereoCameraModel
loadRosCameraInfo(const std::string& left_path, const std::string& right_path)
{
  const YAML::Node left = loadYamlFile(left_path);
  const YAML::Node right = loadYamlFile(right_path);
  ProjectionMatrix p_left{}, p_right{};
  const std::vector<double> left_data =
    readMatrix(left, "projection_matrix", 3, 4, left_path);
  const std::vector<double> right_data =
    readMatrix(right, "projection_matrix", 3, 4, right_path);
  std::copy(left_data.begin(), left_data.end(), p_left.begin());
  std::copy(right_data.begin(), right_data.end(), p_right.begin());
  checkRectifiedIntrinsics(right_path + " (projection_matrix)", p_left, p_right);

  StereoCameraModel model;
  model.calibration = calibrationFromProjections(p_left, p_right);
  model.calibration.width = readScalar<int>(left, "image_width", left_path);
  model.calibration.height = readScalar<int>(left, "image_height", left_path);
  const int right_width = readScalar<int>(right, "image_width", right_path);
  const int right_height = readScalar<int>(right, "image_height", right_path);
  if (right_width != model.calibration.width
      || right_height != model.calibration.height)
    throw IOError(right_path + ": image size " + std::to_string(right_width) + "x"
                  + std::to_string(right_height) + " differs from the left camera's ("
                  + left_path + ")");
  model.calibration.validate(right_path);
  return model;
}

/** \brief The lens distortion models a EuRoC / Kalibr camera file may name. */
enum class DistortionModel {
  /** Brown-Conrady radial-tangential: k1 k2 p1 p2 [k3] (OpenCV's pinhole model). */
  RADIAL_TANGENTIAL,
  /** Equidistant fisheye (Kannala-Brandt): theta_d = theta (1 + k1 theta^2 + k2
   * theta^4 + k3 theta^6 + k4 theta^8), k1..k4 (OpenCV's cv::fisheye model). */
  EQUIDISTANT
};

/** \brief The name a EuRoC / Kalibr file gives \a model (for messages). */
const char*
distortionModelName(DistortionModel model)
{
  return model == DistortionModel::EQUIDISTANT ? "equidistant" : "radial-tangential";
}

/** \brief One EuRoC camera: intrinsics, distortion, size and camera-to-body pose. */
struct EurocCamera {
  cv::Matx33d camera_matrix;
  DistortionModel distortion_model{DistortionModel::RADIAL_TANGENTIAL};
  cv::Mat distortion;
  cv::Size size;
  cv::Matx44d body_T_camera;
};

EurocCamera
readEurocCamera(const std::string& path)
{
  const YAML::Node node = loadYamlFile(path);
  // The rectification below is OpenCV's pinhole model with radial-tangential
  // distortion or its fisheye (equidistant) model. Another model (Kalibr also writes
  // "fov", "omni", "double_sphere") would be rectified wrongly without a word, so it
  // is refused by name. Files without the fields are taken as pinhole,
  // radial-tangential.
  const auto optionalName = [&node, &path](const char* key, const char* fallback) {
    const YAML::Node field = node[key];
    if (!field)
      return std::string(fallback);
    if (!field.IsScalar())
      throw IOError(path + ": field '" + key + "' must be a name");
    return field.as<std::string>();
  };
  const std::string camera_model = optionalName("camera_model", "pinhole");
  if (camera_model != "pinhole")
    throw IOError(path + ": camera_model '" + camera_model
                  + "' is not supported; only 'pinhole' cameras are rectified");
  const std::string distortion_name =
    optionalName("distortion_model", "radial-tangential");
  EurocCamera camera;
  if (distortion_name == "radial-tangential" || distortion_name == "radtan")
    camera.distortion_model = DistortionModel::RADIAL_TANGENTIAL;
  else if (distortion_name == "equidistant")
    camera.distortion_model = DistortionModel::EQUIDISTANT;
  else
    throw IOError(path + ": distortion_model '" + distortion_name
                  + "' is not supported; the known models are 'radial-tangential' "
                    "(or 'radtan') and 'equidistant' (fisheye)");
  const std::vector<double> intrinsics = readNumbers(node, "intrinsics", 4, path);
  const YAML::Node distortion_node =
    requireField(node, "distortion_coefficients", path);
  std::vector<double> distortion;
  try {
    distortion = distortion_node.as<std::vector<double>>();
  } catch (const YAML::Exception&) {
    throw IOError(path + ": field 'distortion_coefficients' must be a list of numbers");
  }
  // radial-tangential: k1 k2 p1 p2 [k3]; equidistant: k1 k2 k3 k4.
  if (camera.distortion_model == DistortionModel::EQUIDISTANT) {
    if (distortion.size() != 4)
      throw IOError(path
                    + ": field 'distortion_coefficients' must hold 4 numbers "
                      "(k1 k2 k3 k4) for the equidistant model");
  } else if (distortion.size() != 4 && distortion.size() != 5)
    throw IOError(path + ": field 'distortion_coefficients' must hold 4 or 5 numbers");
  for (const double coefficient : distortion)
    if (!std::isfinite(coefficient))
      throw IOError(path
                    + ": field 'distortion_coefficients' holds a non-finite number");
  const std::vector<double> resolution = readNumbers(node, "resolution", 2, path);
  const std::vector<double> pose = readMatrix(node, "T_BS", 4, 4, path);

  camera.camera_matrix = cv::Matx33d(intrinsics[0], 0.0, intrinsics[2], 0.0,
                                     intrinsics[1], intrinsics[3], 0.0, 0.0, 1.0);
  if (!(intrinsics[0] > 0.0) || !(intrinsics[1] > 0.0))
    throw IOError(path + ": field 'intrinsics' needs positive focal lengths fu, fv");
  camera.distortion = cv::Mat(distortion, true).reshape(1, 1);
  // The rectification maps take 16 bytes per pixel: the bound keeps them below 2 GB.
  if (!(resolution[0] >= 1.0 && resolution[0] <= MAX_IMAGE_SIDE_PX)
      || !(resolution[1] >= 1.0 && resolution[1] <= MAX_IMAGE_SIDE_PX))
    throw IOError(path + ": field 'resolution' must be a width and height in [1, "
                  + std::to_string(MAX_IMAGE_SIDE_PX) + "] pixels");
  camera.size =
    cv::Size(static_cast<int>(resolution[0]), static_cast<int>(resolution[1]));
  for (int i = 0; i < 16; ++i)
    camera.body_T_camera(i / 4, i % 4) = pose[static_cast<std::size_t>(i)];
  return camera;
}

StereoCameraModel
loadEuroc(const std::string& left_path, const std::string& right_path)
{
  const EurocCamera left = readEurocCamera(left_path);
  const EurocCamera right = readEurocCamera(right_path);
  if (left.size != right.size)
    throw IOError(right_path + ": resolution differs from the left camera's ("
                  + left_path + ")");
  // OpenCV rectifies a pair in one model: a pinhole and a fisheye camera together
  // would need a rectification of their own.
  if (left.distortion_model != right.distortion_model)
    throw IOError(right_path + ": distortion_model '"
                  + distortionModelName(right.distortion_model)
                  + "' differs from the left camera's '"
                  + distortionModelName(left.distortion_model) + "' (" + left_path
                  + "); both cameras of a pair must use the same model");

  // Pose of cam1 in cam0: T_BS(cam0)^-1 * T_BS(cam1). OpenCV wants the opposite
  // transform, taking cam0 points into cam1: X1 = R X0 + T.
  const cv::Matx44d left_T_right = left.body_T_camera.inv() * right.body_T_camera;
  const cv::Matx44d right_T_left = left_T_right.inv();
  const cv::Matx33d rotation = right_T_left.get_minor<3, 3>(0, 0);
  const cv::Vec3d translation(right_T_left(0, 3), right_T_left(1, 3),
                              right_T_left(2, 3));

  if (!(cv::norm(translation) > 0.0))
    throw IOError(right_path
                  + ": field 'T_BS' puts the right camera at the left one's "
                    "place ("
                  + left_path + "): the baseline is zero");

  cv::Mat r1, r2, p1, p2, q;
  StereoCameraModel model;
  // OpenCV asserts on degenerate input (a singular T_BS, a distortion it cannot
  // invert): that is a bad file, reported as such, so that the caller sees one
  // exception type for every bad calibration.
  try {
    if (left.distortion_model == DistortionModel::EQUIDISTANT) {
      // The fisheye model's own rectification: balance 0 takes the focal length
      // that leaves no invalid pixel in the rectified images (as alpha = 0 does for
      // the pinhole model), with the principal points made equal.
      cv::fisheye::stereoRectify(
        left.camera_matrix, left.distortion, right.camera_matrix, right.distortion,
        left.size, rotation, translation, r1, r2, p1, p2, q,
        cv::fisheye::CALIB_ZERO_DISPARITY, left.size, 0.0, 1.0);
      cv::fisheye::initUndistortRectifyMap(
        left.camera_matrix, left.distortion, r1, p1, left.size, CV_32FC1,
        model.rectifier.map_left_x, model.rectifier.map_left_y);
      cv::fisheye::initUndistortRectifyMap(
        right.camera_matrix, right.distortion, r2, p2, right.size, CV_32FC1,
        model.rectifier.map_right_x, model.rectifier.map_right_y);
    } else {
      cv::stereoRectify(left.camera_matrix, left.distortion, right.camera_matrix,
                        right.distortion, left.size, rotation, translation, r1, r2, p1,
                        p2, q, cv::CALIB_ZERO_DISPARITY, 0.0);
      cv::initUndistortRectifyMap(left.camera_matrix, left.distortion, r1, p1,
                                  left.size, CV_32FC1, model.rectifier.map_left_x,
                                  model.rectifier.map_left_y);
      cv::initUndistortRectifyMap(right.camera_matrix, right.distortion, r2, p2,
                                  right.size, CV_32FC1, model.rectifier.map_right_x,
                                  model.rectifier.map_right_y);
    }
  } catch (const cv::Exception& e) {
    throw IOError(left_path + ", " + right_path
                  + ": cannot rectify the pair (OpenCV: " + e.what() + ")");
  }

  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 3; ++col)
      model.rectified_R_left(row, col) = r1.at<double>(row, col);
  model.body_T_left.matrix() = Eigen::Matrix4d::Identity();
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 4; ++col)
      model.body_T_left.matrix()(row, col) = left.body_T_camera(row, col);

  StereoCalibration& calibration = model.calibration;
  calibration.focal_length_px = p1.at<double>(0, 0);
  calibration.cx_px = p1.at<double>(0, 2);
  calibration.cy_px = p1.at<double>(1, 2);
  calibration.baseline_m = -p2.at<double>(0, 3) / p2.at<double>(0, 0);
  calibration.width = left.size.width;
  calibration.height = left.size.height;
  return model;
}

} // namespace

namespace {

/** Every calibration format with its name in the configuration. */
const std::pair<CalibrationFormat, const char*> CALIBRATION_FORMATS[] = {
  {CalibrationFormat::KARLSRUHE, "karlsruhe"},
  {CalibrationFormat::KITTI, "kitti"},
  {CalibrationFormat::ROS_CAMERA_INFO, "ros_camera_info"},
  {CalibrationFormat::EUROC, "euroc"},
};

} // namespace

CalibrationFormat
calibrationFormatFromString(const std::string& name)
{
  for (const auto& [format, format_name] : CALIBRATION_FORMATS)
    if (name == format_name)
      return format;
  throw Exception("unknown calibration format '" + name
                  + "'; known formats: " + knownCalibrationFormats());
}

std::string
calibrationFormatName(CalibrationFormat format)
{
  for (const auto& [known, format_name] : CALIBRATION_FORMATS)
    if (known == format)
      return format_name;
  return "?";
}

std::string
knownCalibrationFormats()
{
  std::string list;
  for (const auto& entry : CALIBRATION_FORMATS)
    list += (list.empty() ? "" : ", ") + std::string(entry.second);
  return list;
}

void
StereoRectifier::rectify(const cv::Mat& left,
                         const cv::Mat& right,
                         cv::Mat& left_rectified,
                         cv::Mat& right_rectified) const
{
  if (empty()) {
    left.copyTo(left_rectified);
    right.copyTo(right_rectified);
    return;
  }
  if (left.size() != map_left_x.size() || right.size() != map_right_x.size())
    throw Exception("StereoRectifier::rectify: the images must be "
                    + std::to_string(map_left_x.cols) + "x"
                    + std::to_string(map_left_x.rows)
                    + ", the size the calibration was made for");
  cv::remap(left, left_rectified, map_left_x, map_left_y, cv::INTER_LINEAR);
  cv::remap(right, right_rectified, map_right_x, map_right_y, cv::INTER_LINEAR);
}

StereoCameraModel
loadStereoCalibration(CalibrationFormat format,
                      const std::string& path,
                      const std::string& right_path)
{
  checkRegularFile(path);
  if (!right_path.empty())
    checkRegularFile(right_path);
  StereoCameraModel model;
  switch (format) {
    case CalibrationFormat::KARLSRUHE:
      model = loadTextCalibration(path, "P1_roi:", "P2_roi:", false);
      break;
    case CalibrationFormat::KITTI:
      model = loadTextCalibration(path, "P0:", "P1:", true);
      break;
    case CalibrationFormat::ROS_CAMERA_INFO:
      if (right_path.empty())
        throw IOError(path
                      + ": the ROS camera_info format needs the right camera's file");
      model = loadRosCameraInfo(path, right_path);
      break;
    case CalibrationFormat::EUROC:
      if (right_path.empty())
        throw IOError(path + ": the EuRoC format needs the right camera's file");
      model = loadEuroc(path, right_path);
      break;
  }
  model.calibration.validate(path);
  return model;
}

} // namespace planar_grid
