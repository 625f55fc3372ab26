// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/ros_bag/ros_messages.h>
#include <planar_grid/ros_bag/transform_table.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace planar_grid {

namespace {

/** A time in seconds, for messages. */
std::string
stampText(double t)
{
  std::ostringstream out;
  out.precision(15);
  out << t << " s";
  return out.str();
}

} // namespace

void
TransformTable::add(const tf2_msgs::TFMessage& message,
                    bool is_static,
                    const std::string& where)
{
  for (const auto& t : message.transforms) {
    Edge& edge = edges_[t.child_frame_id];
    if (!edge.parent.empty() && edge.parent != t.header.frame_id)
      throw IOError(where + ": frame '" + t.child_frame_id + "' has two parents, '"
                    + edge.parent + "' and '" + t.header.frame_id + "'");
    edge.parent = t.header.frame_id;
    edge.is_static = edge.is_static || is_static;
    const Eigen::Isometry3d pose = ros_messages::isometryFromTransform(
      t.transform,
      where + ": '" + t.header.frame_id + "' -> '" + t.child_frame_id + "'");
    edge.samples.push_back({t.header.stamp.toSec(), pose});
  }
}

void
TransformTable::sort()
{
  for (auto& [child, edge] : edges_)
    std::stable_sort(
      edge.samples.begin(), edge.samples.end(),
      [](const Sample& a, const Sample& b) { return a.stamp < b.stamp; });
}

Eigen::Isometry3d
TransformTable::lookup(const std::string& parent,
                       const std::string& child,
                       double t,
                       double tolerance,
                       const std::string& where) const
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  std::string frame = child;
  std::string chain = child;
  while (frame != parent) {
    const auto found = edges_.find(frame);
    // A chain longer than any real one is a loop of frames.
    if (found == edges_.end() || chain.size() > 100000) {
      std::string known;
      for (const auto& [name, edge] : edges_)
        known += (known.empty() ? "" : ", ") + edge.parent + " -> " + name;
      throw IOError(where + ": no chain of transforms from '" + parent + "' to '"
                    + child + "' (followed " + chain
                    + " up to its root); the transforms: "
                    + (known.empty() ? "none" : known));
    }
    pose = at(found->second, frame, t, tolerance, where) * pose;
    frame = found->second.parent;
    chain += " <- " + frame;
  }
  return pose;
}

Eigen::Isometry3d
TransformTable::at(const Edge& edge,
                   const std::string& child,
                   double t,
                   double tolerance,
                   const std::string& where) const
{
  const auto& s = edge.samples;
  if (edge.is_static)
    return s.back().parent_T_child;
  if (t <= s.front().stamp || t >= s.back().stamp) {
    const Sample& end = t <= s.front().stamp ? s.front() : s.back();
    if (std::abs(t - end.stamp) <= tolerance)
      return end.parent_T_child;
    throw IOError(where + ": no transform '" + edge.parent + "' -> '" + child + "' at "
                  + stampText(t) + ": its samples span " + stampText(s.front().stamp)
                  + " to " + stampText(s.back().stamp)
                  + " (input.poses.max_time_difference_s " + std::to_string(tolerance)
                  + " s)");
  }
  const auto after =
    std::upper_bound(s.begin(), s.end(), t,
                     [](double v, const Sample& sample) { return v < sample.stamp; });
  const Sample& b = *after;
  const Sample& a = *(after - 1);
  const double w = b.stamp > a.stamp ? (t - a.stamp) / (b.stamp - a.stamp) : 0.0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Quaterniond(a.parent_T_child.linear())
                    .slerp(w, Eigen::Quaterniond(b.parent_T_child.linear()))
                    .toRotationMatrix();
  pose.translation() =
    (1.0 - w) * a.parent_T_child.translation() + w * b.parent_T_child.translation();
  return pose;
}

} // namespace planar_grid
