// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>

#include <pcl/filters/filter_indices.h>
#include <pcl/point_cloud.h>

#include <string>

namespace planar_grid {

/** \brief The valid range of each FastStatisticalOutlierRemoval parameter, declared
 * once: filter() tests the value against it and the pipeline's
 * statistical_outlier_removal stage table takes it as its range. \ingroup filters */
namespace fast_statistical_outlier_removal_ranges {
/** \brief Nearest neighbours whose mean distance is tested: [1, inf), as
 * pcl::StatisticalOutlierRemoval takes it. */
inline constexpr ParamRange MEAN_K = ParamRange::openMax(1, ParamRange::UNBOUNDED);
/** \brief Multiplier of the standard deviation in the threshold: [0, 100]. */
inline constexpr ParamRange STDDEV_MUL_THRESH = ParamRange::closed(0.0, 100.0);
} // namespace fast_statistical_outlier_removal_ranges

/** \brief FastStatisticalOutlierRemoval's parameters; their declarations are
 * fastStatisticalOutlierRemovalParamDeclarations(). The defaults are the pipeline's
 * statistical_outlier_removal stage's (pcl::StatisticalOutlierRemoval's 1 and 0
 * remove next to nothing). \ingroup filters */
struct FastStatisticalOutlierRemovalParams {
  /** \brief Nearest neighbours whose mean distance is tested. */
  int mean_k{20};
  /** \brief Multiplier of the standard deviation of the mean distances in the
   * threshold mean + stddev_mul_thresh * stddev. */
  double stddev_mul_thresh{2.0};
};

/** \brief The one declaration of each FastStatisticalOutlierRemovalParams member (key,
 * range, meaning). \ingroup filters */
const ParamDeclarations<FastStatisticalOutlierRemovalParams>&
fastStatisticalOutlierRemovalParamDeclarations();

/** \brief pcl::StatisticalOutlierRemoval's filter with a faster neighbour search: the
 * same points kept, in the same order, for the same parameters.
 *
 * For each point, the mean Euclidean distance to its mean_k nearest neighbours (the
 * point itself excluded) is computed; a point whose mean distance exceeds
 * mean + stddev_mul_thresh * stddev over the finite points is an outlier. As in PCL, a
 * non-finite point gets the mean distance 0 and is kept, and setNegative() returns the
 * outliers instead. The output cloud is built by pcl::FilterIndices, as for PCL's
 * filter.
 *
 * The k nearest neighbours of most points are found among the points of the 3 x 3 x 3
 * cells (edge 1.25 times the median k-th neighbour distance of a sample) around the
 * point's cell, or else of the 5 x 5 x 5 cells, accepted only when the k-th distance is
 * shorter than the distance to the outside of those cells, so that no other point can
 * be nearer; the few left come from nanoflann's exact kd-tree (the library wrapped)
 * instead of pcl::search::KdTree.
 * Distances are the same single precision squared distances summed over x, y, z, and
 * their sums are exact in double precision, so the classification equals PCL's on an
 * unorganized cloud. An organized cloud is searched exactly here, where PCL uses
 * pcl::search::OrganizedNeighbor's image-window search. Timings against PCL's filter
 * on a Karlsruhe frame are in docs/BENCHMARKS.md (bench_pipeline_stages).
 * Precompiled for the point types of PLANAR_GRID_POINT_TYPES; any other type is
 * instantiated from the impl/ header when PCL_NO_PRECOMPILE is defined, as with PCL.
 * \ingroup filters */
template <typename PointT>
class FastStatisticalOutlierRemoval : public pcl::FilterIndices<PointT> {
public:
  /** \brief The filtered cloud type, pcl::PointCloud<PointT>. */
  using PointCloud = typename pcl::FilterIndices<PointT>::PointCloud;

  /** \brief The parameters (FastStatisticalOutlierRemovalParams). */
  using Params = FastStatisticalOutlierRemovalParams;

  /** \brief Each parameter's one declaration: the statistical_outlier_removal stage
   * and its reference are made from it.
   * \return fastStatisticalOutlierRemovalParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return fastStatisticalOutlierRemovalParamDeclarations();
  }

  /** \param[in] extract_removed_indices keep the removed indices (getRemovedIndices())
   */
  explicit FastStatisticalOutlierRemoval(bool extract_removed_indices = false) :
      pcl::FilterIndices<PointT>(extract_removed_indices)
  {
    this->filter_name_ = "FastStatisticalOutlierRemoval";
  }

  /** \brief Sets both parameters (checked by filter()). */
  void setParams(const Params& params) { params_ = params; }
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Number of nearest neighbours whose mean distance is tested (in
   * fast_statistical_outlier_removal_ranges::MEAN_K; 20 by default, the pipeline's;
   * pcl::StatisticalOutlierRemoval's is 1). */
  void setMeanK(int mean_k) { params_.mean_k = mean_k; }
  /** \brief The number of neighbours. */
  int getMeanK() const { return params_.mean_k; }

  /** \brief Multiplier of the standard deviation of the mean distances in the
   * threshold mean + std_mul * stddev (finite, else filter() throws
   * planar_grid::Exception; 2 by default, the pipeline's; PCL's is 0). */
  void setStddevMulThresh(double std_mul) { params_.stddev_mul_thresh = std_mul; }
  /** \brief The multiplier. */
  double getStddevMulThresh() const { return params_.stddev_mul_thresh; }

protected:
  /** \brief Indices of the kept points (or, with setNegative(true), the outliers).
   * \throws planar_grid::Exception for mean_k < 1 or a stddev_mul_thresh that is not
   * finite */
  void applyFilter(pcl::Indices& indices) override;

private:
  /** \brief The parameters. */
  Params params_;
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/fast_statistical_outlier_removal.hpp>
#endif
