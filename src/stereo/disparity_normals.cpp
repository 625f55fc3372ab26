// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/disparity_normals.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <string>
#include <utility>

namespace planar_grid {

namespace {

/** Wide windows are read at a stride: about 2 x HALF_SAMPLES + 1 pixels a side. */
constexpr int HALF_SAMPLES = 7;

/** Points whose windows are summed side by side: each point's sums are a chain of
 * dependent additions, so several points in one loop keep the adder busy. */
constexpr std::size_t GROUP = 4;

/** \a value where \a keep, else +0, without a branch (the pixels' outcomes are too
 * irregular for the branch predictor). */
inline double
keptOrZero(double value, bool keep)
{
  std::uint64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  bits &= std::uint64_t{0} - static_cast<std::uint64_t>(keep);
  std::memcpy(&value, &bits, sizeof(bits));
  return value;
}

/** One point's window: its pixel, its own disparity and the gate around it, the
 * sampled offsets (-half .. half times stride) and the columns and rows of them
 * inside the image. */
struct Window {
  long ui{0}, vi{0};
  double own{0.0}, gate{0.0}, min_count{0.0};
  int stride{1}, half{0};
  int i_first{0}, i_last{0};
  /** Every sampled pixel lies inside the image. */
  bool inside{false};
};

/** The least-squares sums of d = a du + b dv + c0 over a window, du and dv relative to
 * the point's pixel. Those of the pixel offsets alone are sums of integers, kept
 * exactly in integers; those with the disparity in double, centred on the point's
 * own disparity (better conditioned). */
struct WindowSums {
  std::int64_t n{0}, su{0}, sv{0}, suu{0}, suv{0}, svv{0};
  double sd{0.0}, sud{0.0}, svd{0.0};

  /** Adds one row's integer sums at row offset \a dv_int. */
  void addRow(std::int64_t row_n,
              std::int64_t row_su,
              std::int64_t row_suu,
              std::int64_t dv_int)
  {
    n += row_n;
    su += row_su;
    sv += row_n * dv_int;
    suu += row_suu;
    suv += row_su * dv_int;
    svv += row_n * dv_int * dv_int;
  }
};

/** The window of the camera-frame point \a p, or false when it projects outside the
 * image or lies behind the camera. */
bool
makeWindow(const Eigen::Vector3f& p,
           const cv::Mat& disparity,
           const StereoCalibration& calibration,
           const DisparityNormalParams& params,
           Window& w)
{
  if (!p.allFinite() || !(p.z() > 0.0f))
    return false;
  const double f = calibration.focal_length_px;
  const double u = f * p.x() / p.z() + calibration.cx_px;
  const double v = f * p.y() / p.z() + calibration.cy_px;
  w.ui = std::lround(u);
  w.vi = std::lround(v);
  if (w.ui < 0 || w.vi < 0 || w.ui >= disparity.cols || w.vi >= disparity.rows)
    return false;
  w.own = f * calibration.baseline_m / p.z();
  w.gate = std::max(2.0, 0.2 * w.own);
  const int r = static_cast<int>(
    std::clamp<double>(std::round(f * params.window_radius_m / p.z()),
                       params.min_window_radius_px, params.max_window_radius_px));
  w.stride = std::max(1, (r + HALF_SAMPLES - 1) / HALF_SAMPLES);
  w.half = r / w.stride;
  w.min_count =
    std::max(3.0, params.min_valid_fraction * (2 * w.half + 1) * (2 * w.half + 1));
  // the window's columns inside the image
  const long reach = static_cast<long>(w.half) * w.stride;
  w.i_first = -w.half;
  w.i_last = w.half;
  const long col_first = w.ui - reach;
  if (col_first < 0)
    w.i_first += static_cast<int>((-col_first + w.stride - 1) / w.stride);
  const long col_last = w.ui + reach;
  if (col_last >= disparity.cols)
    w.i_last -= static_cast<int>((col_last - disparity.cols + w.stride) / w.stride);
  w.inside = col_first >= 0 && col_last < disparity.cols && w.vi - reach >= 0
             && w.vi + reach < disparity.rows;
  return true;
}

/** The sums of one window, rows and columns in increasing order. A pixel that does
 * not take part adds 0 to every sum, which leaves each sum as it was (none of them is
 * ever -0), so the sums are those of the taking part pixels alone, in the same
 * order, without a branch. */
WindowSums
sumWindow(const cv::Mat& disparity, const Window& w)
{
  WindowSums s;
  for (int j = -w.half; j <= w.half; ++j) {
    const long row = w.vi + static_cast<long>(j) * w.stride;
    if (row < 0 || row >= disparity.rows)
      continue;
    const float* line = disparity.ptr<float>(static_cast<int>(row));
    const std::int64_t dv_int = row - w.vi;
    const auto dv = static_cast<double>(dv_int);
    std::int64_t row_n = 0, row_su = 0, row_suu = 0;
    for (int i = w.i_first; i <= w.i_last; ++i) {
      const long col = w.ui + static_cast<long>(i) * w.stride;
      const double d = line[col];
      const bool takes_part = (d > 0.0) & (std::abs(d - w.own) <= w.gate);
      const std::int64_t du_int = col - w.ui;
      const auto du = static_cast<double>(du_int);
      const double e = keptOrZero(d - w.own, takes_part);
      const std::int64_t m = takes_part ? 1 : 0;
      row_n += m;
      row_su += m * du_int;
      row_suu += m * du_int * du_int;
      s.sd += e;
      s.sud += du * e;
      s.svd += dv * e;
    }
    s.addRow(row_n, row_su, row_suu, dv_int);
  }
  return s;
}

/** The sums of GROUP windows of the same half-width and stride, each inside the
 * image, side by side: each window's sums take the same values in the same order as
 * sumWindow() gives them. */
std::array<WindowSums, GROUP>
sumWindows(const cv::Mat& disparity, const std::array<const Window*, GROUP>& w)
{
  std::array<WindowSums, GROUP> s;
  const int half = w[0]->half, stride = w[0]->stride;
  for (int j = -half; j <= half; ++j) {
    const std::int64_t dv_int = static_cast<std::int64_t>(j) * stride;
    const auto dv = static_cast<double>(dv_int);
    std::array<const float*, GROUP> line;
    std::array<double, GROUP> own, gate;
    for (std::size_t g = 0; g < GROUP; ++g) {
      line[g] = disparity.ptr<float>(static_cast<int>(w[g]->vi + dv_int)) + w[g]->ui;
      own[g] = w[g]->own;
      gate[g] = w[g]->gate;
    }
    std::array<std::int64_t, GROUP> row_n{}, row_su{}, row_suu{};
    std::array<double, GROUP> sd, sud, svd;
    for (std::size_t g = 0; g < GROUP; ++g) {
      sd[g] = s[g].sd;
      sud[g] = s[g].sud;
      svd[g] = s[g].svd;
    }
    for (int i = -half; i <= half; ++i) {
      const std::int64_t du_int = static_cast<std::int64_t>(i) * stride;
      const auto du = static_cast<double>(du_int);
      for (std::size_t g = 0; g < GROUP; ++g) {
        const double d = line[g][du_int];
        const bool takes_part = (d > 0.0) & (std::abs(d - own[g]) <= gate[g]);
        const double e = keptOrZero(d - own[g], takes_part);
        const std::int64_t m = takes_part ? 1 : 0;
        row_n[g] += m;
        row_su[g] += m * du_int;
        row_suu[g] += m * du_int * du_int;
        sd[g] += e;
        sud[g] += du * e;
        svd[g] += dv * e;
      }
    }
    for (std::size_t g = 0; g < GROUP; ++g) {
      s[g].sd = sd[g];
      s[g].sud = sud[g];
      s[g].svd = svd[g];
      s[g].addRow(row_n[g], row_su[g], row_suu[g], dv_int);
    }
  }
  return s;
}

/** The unit normal of the plane fitted to a window's sums, in the camera frame and
 * toward the camera (the point \a p's line of sight meets it at n . p < 0), or NaN
 * when too few pixels take part or they do not fix a plane. */
Eigen::Vector3f
windowNormal(const WindowSums& s,
             const Window& w,
             const StereoCalibration& calibration,
             const Eigen::Vector3f& p)
{
  const Eigen::Vector3f nan =
    Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  if (static_cast<double>(s.n) < w.min_count)
    return nan;
  Eigen::Matrix3d normal_matrix;
  normal_matrix << static_cast<double>(s.suu), static_cast<double>(s.suv),
    static_cast<double>(s.su), static_cast<double>(s.suv), static_cast<double>(s.svv),
    static_cast<double>(s.sv), static_cast<double>(s.su), static_cast<double>(s.sv),
    static_cast<double>(s.n);
  const Eigen::Vector3d rhs(s.sud, s.svd, s.sd);
  // The sums of the pixel offsets are exact integers: the samples are collinear (no
  // plane fits them) exactly when the determinant of their normal matrix is zero.
  // It is computed exactly: with at most 15 x 15 samples of offsets |du|, |dv| <= 200
  // px, every sum is below 2^24 and every product of three below 2^62.
  const std::int64_t det = s.suu * (s.svv * s.n - s.sv * s.sv)
                           - s.suv * (s.suv * s.n - s.sv * s.su)
                           + s.su * (s.suv * s.sv - s.svv * s.su);
  if (det == 0)
    return nan;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(normal_matrix);
  if (ldlt.info() != Eigen::Success)
    return nan;
  const Eigen::Vector3d abc = ldlt.solve(rhs);
  const double a = abc[0], b = abc[1];
  const double f = calibration.focal_length_px;
  // Disparity at pixel (0, 0): c = own + c0 - a ui - b vi.
  const double c =
    w.own + abc[2] - a * static_cast<double>(w.ui) - b * static_cast<double>(w.vi);
  Eigen::Vector3d normal(a * f, b * f,
                         c + a * calibration.cx_px + b * calibration.cy_px);
  const double length = normal.norm();
  if (!(length > 0.0) || !std::isfinite(length))
    return nan;
  normal /= length;
  if (normal.dot(p.cast<double>()) > 0.0)
    normal = -normal;
  return normal.cast<float>();
}

} // namespace

void
estimateDisparityNormals(
  const cv::Mat& disparity,
  const StereoCalibration& calibration,
  const std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>&
    points_camera,
  const DisparityNormalParams& params,
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>& normals)
{
  namespace ranges = disparity_normals_ranges;
  if (!disparity.empty() && disparity.type() != CV_32FC1)
    throw Exception("estimateDisparityNormals: the disparity must be CV_32FC1");
  const double f = calibration.focal_length_px;
  const double fb = f * calibration.baseline_m;
  if (!(f > 0.0) || !(fb > 0.0) || !std::isfinite(fb))
    throw Exception("estimateDisparityNormals: the calibration needs a positive focal "
                    "length and baseline");
  if (!ranges::WINDOW_RADIUS.contains(params.window_radius_m))
    throw Exception(paramRangeMessage("window_radius_m", ranges::WINDOW_RADIUS, "m"));
  if (!ranges::WINDOW_RADIUS_PX.contains(params.min_window_radius_px)
      || !ranges::WINDOW_RADIUS_PX.contains(params.max_window_radius_px)
      || params.min_window_radius_px > params.max_window_radius_px)
    throw Exception("estimateDisparityNormals: min_window_radius_px and "
                    "max_window_radius_px must be in [1, 200] px, the first no larger "
                    "than the second");
  if (!ranges::MIN_VALID_FRACTION.contains(params.min_valid_fraction))
    throw Exception(
      paramRangeMessage("min_valid_fraction", ranges::MIN_VALID_FRACTION, ""));

  const float nan = std::numeric_limits<float>::quiet_NaN();
  normals.assign(points_camera.size(), Eigen::Vector3f::Constant(nan));
  if (disparity.empty())
    return;
  // The windows inside the image, by half-width and stride, go GROUP at a time; the
  // rest (a window cut by the image's border, the last few of a size) one by one.
  // Each size's windows in image row order, so that the rows one window reads are
  // still cached for the next (a counting sort of the points by row).
  std::vector<Window> windows(points_camera.size());
  std::vector<std::size_t> row_start(static_cast<std::size_t>(disparity.rows) + 1, 0);
  for (std::size_t k = 0; k < points_camera.size(); ++k) {
    Window& w = windows[k];
    if (makeWindow(points_camera[k], disparity, calibration, params, w))
      ++row_start[static_cast<std::size_t>(w.vi) + 1];
    else
      w.half = -1;
  }
  for (std::size_t v = 1; v < row_start.size(); ++v)
    row_start[v] += row_start[v - 1];
  std::vector<std::size_t> by_row(row_start.back());
  for (std::size_t k = 0; k < points_camera.size(); ++k)
    if (windows[k].half >= 0)
      by_row[row_start[static_cast<std::size_t>(windows[k].vi)]++] = k;
  std::map<std::pair<int, int>, std::vector<std::size_t>> by_size;
  for (const std::size_t k : by_row) {
    const Window& w = windows[k];
    if (w.inside)
      by_size[{w.half, w.stride}].push_back(k);
    else
      normals[k] =
        windowNormal(sumWindow(disparity, w), w, calibration, points_camera[k]);
  }
  for (const auto& size : by_size) {
    const std::vector<std::size_t>& ks = size.second;
    std::size_t t = 0;
    for (; t + GROUP <= ks.size(); t += GROUP) {
      std::array<const Window*, GROUP> group;
      for (std::size_t g = 0; g < GROUP; ++g)
        group[g] = &windows[ks[t + g]];
      const std::array<WindowSums, GROUP> sums = sumWindows(disparity, group);
      for (std::size_t g = 0; g < GROUP; ++g)
        normals[ks[t + g]] =
          windowNormal(sums[g], *group[g], calibration, points_camera[ks[t + g]]);
    }
    for (; t < ks.size(); ++t)
      normals[ks[t]] = windowNormal(sumWindow(disparity, windows[ks[t]]),
                                    windows[ks[t]], calibration, points_camera[ks[t]]);
  }
}

} // namespace planar_grid
