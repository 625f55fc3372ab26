// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/memory.h>

#include <Eigen/Geometry>
#include <Eigen/StdVector>
#include <tf2_msgs/TFMessage.h>

#include <map>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief The transforms of a bag's /tf and /tf_static messages, by child frame:
 * parent_T_child over time (meters), looked up along the chain of frames as tf2 does,
 * without a ROS master. A moving transform is interpolated between its samples
 * (translation linearly, rotation by slerp); a static one holds its last sample.
 *
 * Usage: add() every message, sort() once, then lookup(). An empty table has no chain:
 * lookup() throws. \ingroup ros_bag */
class TransformTable {
public:
  /** \brief Adds the transforms of one message.
   * \param[in] message a tf2_msgs/TFMessage of /tf or /tf_static
   * \param[in] is_static true for /tf_static (its transforms hold at every time)
   * \param[in] where the bag and topic, for the messages
   * \throws planar_grid::IOError when a frame gets a second parent or a rotation is not
   * a unit quaternion */
  void
  add(const tf2_msgs::TFMessage& message, bool is_static, const std::string& where);

  /** \brief Sorts each transform's samples by stamp; call it after the last add(). */
  void sort();

  /** \brief parent_T_child at \a t through the chain of frames from \a child up to
   * \a parent; each moving transform is interpolated between its samples, or the
   * nearest sample within \a tolerance outside them.
   * \param[in] parent the frame the pose is given in
   * \param[in] child the frame whose pose is looked up
   * \param[in] t the time, s (a header stamp in seconds)
   * \param[in] tolerance how far before the first or after the last sample of a moving
   * transform \a t may be, s
   * \param[in] where the bag and topic, for the messages
   * \return parent_T_child, meters
   * \throws planar_grid::IOError when no chain joins the frames (listing the known
   * transforms) or a transform of the chain has no sample near \a t */
  [[nodiscard]] Eigen::Isometry3d lookup(const std::string& parent,
                                         const std::string& child,
                                         double t,
                                         double tolerance,
                                         const std::string& where) const;

private:
  /** \brief One sample of a transform: its stamp (s) and parent_T_child (m). */
  struct Sample {
    double stamp;
    Eigen::Isometry3d parent_T_child;
  };
  /** \brief One transform: its parent frame and samples. */
  struct Edge {
    std::string parent;
    bool is_static{false};
    std::vector<Sample, Eigen::aligned_allocator<Sample>> samples;
  };

  /** \brief The transform of \a edge (to \a child) at \a t. */
  Eigen::Isometry3d at(const Edge& edge,
                       const std::string& child,
                       double t,
                       double tolerance,
                       const std::string& where) const;

  /** \brief The transforms, by child frame. */
  std::map<std::string, Edge> edges_;
};

} // namespace planar_grid
