// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/core/stereo_calibration.h>

#include <pcl/filters/filter_indices.h>
#include <pcl/point_cloud.h>

#include <Eigen/Geometry>

namespace planar_grid {

/** \brief The valid range of each DepthErrorFilter parameter, declared once: filter()
 * tests the value against it and the pipeline's depth_error_filter stage table takes it
 * as its range. \ingroup filters */
namespace depth_error_filter_ranges {
/** \brief Disparity error Delta d of eq. 4, px: [0.01, 10]. */
inline constexpr ParamRange DISPARITY_ERROR = ParamRange::closed(0.01, 10.0);
/** \brief Largest depth error kept, m: [0.001, 100]. */
inline constexpr ParamRange MAX_DEPTH_ERROR = ParamRange::closed(0.001, 100.0);
} // namespace depth_error_filter_ranges

/** \brief DepthErrorFilter's parameters; their declarations are
 * depthErrorFilterParamDeclarations(). \ingroup filters */
struct DepthErrorFilterParams {
  /** \brief Disparity error Delta d of eq. 4, px (the paper's 0.5). */
  double disparity_error_px{0.5};
  /** \brief Largest depth error Delta z of a point kept, m. */
  double max_depth_error_m{0.3};
};

/** \brief The one declaration of each DepthErrorFilterParams member (key with unit,
 * range, meaning). \ingroup filters */
const ParamDeclarations<DepthErrorFilterParams>& depthErrorFilterParamDeclarations();

/** \brief Keeps the points whose stereo depth error is within a bound (paper, eq. 4).
 *
 * A stereo point at depth z (along the optical axis) has the depth error
 * Delta z = z^2 Delta d / (B f) for a disparity error Delta d (px), baseline B (m) and
 * focal length f (px) (StereoCalibration::depthError()). The error grows with the
 * square of the depth, so the bound max_depth_error_m is a depth bound:
 * z <= sqrt(max_depth_error_m B f / Delta d) (getMaxDepth()). The filter keeps the
 * points within it; setNegative(true) returns those beyond it instead. A point's depth
 * is its z in the camera frame, camera_T_cloud p (setCameraTransform(); the identity
 * by default, for a cloud in the camera frame); a point behind the camera (z <= 0) is
 * within the bound. Non-finite points are dropped in either mode (listed in
 * getRemovedIndices()), as by pcl::PassThrough. The output cloud is built by
 * pcl::FilterIndices.
 *
 * Precompiled for the point types of PLANAR_GRID_POINT_TYPES; any other type is
 * instantiated from the impl/ header when PCL_NO_PRECOMPILE is defined, as with PCL.
 * \ingroup filters */
template <typename PointT> class DepthErrorFilter : public pcl::FilterIndices<PointT> {
public:
  /** \brief The filtered cloud type, pcl::PointCloud<PointT>. */
  using PointCloud = typename pcl::FilterIndices<PointT>::PointCloud;

  /** \brief The parameters (DepthErrorFilterParams). */
  using Params = DepthErrorFilterParams;

  /** \brief Each parameter's one declaration: the depth_error_filter stage and its
   * reference are made from it. \return depthErrorFilterParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return depthErrorFilterParamDeclarations();
  }

  /** \param[in] extract_removed_indices keep the removed indices (getRemovedIndices())
   */
  explicit DepthErrorFilter(bool extract_removed_indices = false) :
      pcl::FilterIndices<PointT>(extract_removed_indices)
  {
    this->filter_name_ = "DepthErrorFilter";
  }

  /** \brief The rectified stereo rig's baseline and focal length (the rest is not
   * used). */
  void setCalibration(const StereoCalibration& calibration)
  {
    calibration_ = calibration;
  }
  /** \brief The calibration. */
  const StereoCalibration& getCalibration() const { return calibration_; }

  /** \brief Sets both parameters (checked by filter() and getMaxDepth()). */
  void setParams(const Params& params) { params_ = params; }
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Disparity error Delta d of eq. 4, px (the paper's 0.5 px by default; in
   * depth_error_filter_ranges::DISPARITY_ERROR). */
  void setDisparityError(double disparity_error_px)
  {
    params_.disparity_error_px = disparity_error_px;
  }
  /** \brief The disparity error, px. */
  double getDisparityError() const { return params_.disparity_error_px; }

  /** \brief Largest depth error Delta z of a point kept, m (0.3 by default; in
   * depth_error_filter_ranges::MAX_DEPTH_ERROR). */
  void setMaxDepthError(double max_depth_error_m)
  {
    params_.max_depth_error_m = max_depth_error_m;
  }
  /** \brief The bound, m. */
  double getMaxDepthError() const { return params_.max_depth_error_m; }

  /** \brief Rigid transform from the cloud's frame to the camera's (z along the
   * optical axis), m; the identity by default. */
  void setCameraTransform(const Eigen::Affine3f& camera_T_cloud)
  {
    camera_T_cloud_ = camera_T_cloud;
  }
  /** \brief The transform. */
  const Eigen::Affine3f& getCameraTransform() const { return camera_T_cloud_; }

  /** \brief The depth bound, m: sqrt(max_depth_error_m / Delta z(1 m)).
   * \throws planar_grid::Exception naming the parameter for a value out of its range
   * or a calibration whose baseline or focal length is not finite and positive */
  double getMaxDepth() const;

protected:
  /** \brief Indices of the points within the depth bound (or, with setNegative(true),
   * the finite points beyond it).
   * \throws planar_grid::Exception as getMaxDepth() */
  void applyFilter(pcl::Indices& indices) override;

private:
  StereoCalibration calibration_;
  /** \brief The parameters. */
  Params params_;
  Eigen::Affine3f camera_T_cloud_{Eigen::Affine3f::Identity()};
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/depth_error_filter.hpp>
#endif
