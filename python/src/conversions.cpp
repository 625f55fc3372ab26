// SPDX-License-Identifier: BSD-3-Clause
#include <cmath>
#include <sstream>
#include <string>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

std::string
shapeText(const py::array& array)
{
  std::ostringstream text;
  text << "(";
  for (py::ssize_t d = 0; d < array.ndim(); ++d)
    text << (d ? ", " : "") << array.shape(d);
  text << (array.ndim() == 1 ? ",)" : ")");
  return text.str();
}

} // namespace

pcl::PointCloud<pcl::PointXYZ>::Ptr
toCloud(const FloatArray& points, const char* name)
{
  if (points.ndim() != 2 || points.shape(1) != 3)
    throw py::value_error(std::string(name)
                          + " must be an (N, 3) array of x, y, z in "
                            "meters, got shape "
                          + shapeText(points));
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  const auto n = static_cast<std::size_t>(points.shape(0));
  cloud->resize(n);
  cloud->width = static_cast<std::uint32_t>(n);
  cloud->height = 1;
  const auto p = points.unchecked<2>();
  bool dense = true;
  for (std::size_t i = 0; i < n; ++i) {
    const auto i_py = static_cast<py::ssize_t>(i);
    auto& q = (*cloud)[i];
    q.x = p(i_py, 0);
    q.y = p(i_py, 1);
    q.z = p(i_py, 2);
    dense = dense && std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z);
  }
  cloud->is_dense = dense;
  return cloud;
}

Eigen::Vector3f
toVector3f(const DoubleArray& vector, const char* name)
{
  if (vector.ndim() != 1 || vector.shape(0) != 3)
    throw py::value_error(std::string(name) + " must be a (3,) array, got shape "
                          + shapeText(vector));
  const auto v = vector.unchecked<1>();
  return Eigen::Vector3d(v(0), v(1), v(2)).cast<float>();
}

std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>
toPoints(const FloatArray& points, const char* name)
{
  if (points.ndim() == 1 && points.shape(0) == 3) {
    const auto v = points.unchecked<1>();
    return {Eigen::Vector3f(v(0), v(1), v(2))};
  }
  if (points.ndim() != 2 || points.shape(1) != 3)
    throw py::value_error(
      std::string(name)
      + " must be an (N, 3) array of x, y, z in meters, or one (3,) "
        "point");
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> out(
    static_cast<std::size_t>(points.shape(0)));
  const auto p = points.unchecked<2>();
  for (py::ssize_t i = 0; i < points.shape(0); ++i)
    out[static_cast<std::size_t>(i)] = Eigen::Vector3f(p(i, 0), p(i, 1), p(i, 2));
  return out;
}

Eigen::Isometry3d
toIsometry(const DoubleArray& matrix, const char* name)
{
  if (matrix.ndim() != 2 || matrix.shape(0) != 4 || matrix.shape(1) != 4)
    throw py::value_error(std::string(name)
                          + " must be a (4, 4) rigid transform, got "
                            "shape "
                          + shapeText(matrix));
  const auto a = matrix.unchecked<2>();
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      m(r, c) = a(r, c);
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  if (!m.allFinite() || !m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1))
      || !(rotation.transpose() * rotation).isIdentity(1e-3)
      || !(rotation.determinant() > 0.0))
    throw py::value_error(
      std::string(name)
      + " must be a rigid transform: a rotation (orthonormal, "
        "determinant 1) and a translation in meters, last row 0 0 0 1");
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation;
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

std::string
wrapText(const std::string& text, std::size_t indent, std::size_t width)
{
  const std::string margin(indent, ' ');
  std::istringstream words(text);
  std::string word, line, out;
  while (words >> word) {
    if (!line.empty() && indent + line.size() + 1 + word.size() > width) {
      out += margin + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty())
    out += margin + line + "\n";
  return out;
}

void
checkInlierIndices(const PlanarSegments& planes,
                   std::size_t point_count,
                   const std::string& who)
{
  for (std::size_t i = 0; i < planes.size(); ++i)
    for (const int index : planes[i].inliers.indices)
      if (index < 0 || static_cast<std::size_t>(index) >= point_count)
        throw py::index_error(who + ": plane " + std::to_string(i)
                              + " has the inlier index " + std::to_string(index)
                              + ", outside the " + std::to_string(point_count)
                              + " points");
}

} // namespace python
} // namespace planar_grid
