// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <opencv2/core.hpp>

#include <cstddef>
#include <string>

namespace planar_grid {

/** \brief What the features of a rectified stereo pair say about its order: ORB key
 * points of both images matched both ways (cross-checked), kept when they lie on the
 * same row (|dy| <= 1 px), counted by the sign of the disparity x_left - x_right. In a
 * pair in the right order nearly every match has a positive disparity; swapped
 * images give negative ones; one image given twice gives zero. \ingroup pipeline */
struct StereoPairOrder {
  /** \brief Matches with a disparity above 0.5 px. */
  std::size_t positive{0};
  /** \brief Matches with a disparity below -0.5 px. */
  std::size_t negative{0};
  /** \brief Matches within 0.5 px of zero disparity. */
  std::size_t zero{0};
};

/** \brief Counts the matched features of \a left and \a right by disparity sign.
 * \param[in] left, right 8-bit grey images of one size (a rectified pair)
 * \return the counts (all zero for images without texture)
 * \ingroup pipeline */
StereoPairOrder countStereoPairOrder(const cv::Mat& left, const cv::Mat& right);

/** \brief Throws planar_grid::IOError naming both images when the pair is one image
 * given twice (identical pixels, not all of one value) or looks swapped: at least 40
 * row-aligned matches with a non-zero disparity, and more than 3/4 of them negative.
 * Nothing is thrown for a pair whose features say nothing (too little texture).
 * \param[in] left, right 8-bit grey images of one size (a rectified pair)
 * \param[in] left_path, right_path the files, for the message
 * \param[in] remedy what to exchange, for the message of a swapped pair
 * \note The stereo inputs (stereo_sequence, ros_bag) run it on their first pair, before
 * any frame is mapped.
 * \ingroup pipeline */
void checkStereoPairOrder(const cv::Mat& left,
                          const cv::Mat& right,
                          const std::string& left_path,
                          const std::string& right_path,
                          const std::string& remedy =
                            "exchange the left and right inputs (input.left_images "
                            "and right_images; a bag's input.left_image and "
                            "right_image)");

} // namespace planar_grid
