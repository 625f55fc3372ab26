// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>
#include <vector>

namespace planar_grid {

/** \brief One line of a LineChart: the values of one method, drawn in order of the
 * points given. \ingroup visualization */
struct LineSeries {
  /** \brief The legend entry (the method: "PG", "RA", "SG", "OG", ...). */
  std::string name;
  /** \brief Abscissae (e.g. the minimum cell size, metres); finite. */
  std::vector<double> x;
  /** \brief Ordinates, one per abscissa; finite (and > 0 on a log axis). */
  std::vector<double> y;
};

/** \brief A line chart like the paper's Figs. 12-14: one line with markers per method
 * and a legend. \ingroup visualization */
struct LineChart {
  /** \brief Title above the plot ("" = none). */
  std::string title;
  /** \brief Horizontal axis title, with its unit ("minimum cell size [m]"). */
  std::string x_label;
  /** \brief Vertical axis title, with its unit. */
  std::string y_label;
  /** \brief The lines, one per method, each in its own colour and marker. */
  std::vector<LineSeries> series;
  /** \brief Logarithmic vertical axis (every y must then be > 0). */
  bool log_y{false};
};

/** \brief Renders \a chart with VTK charts (vtkChartXY in a vtkContextView) offscreen
 * and writes it as a PNG, atomically: white background, one line per series with
 * markers (circle, square, diamond, cross, plus, in turn) in distinct colours, a
 * legend at the top right. A series without points adds only its legend entry; a chart
 * without series renders the empty axes.
 * \param[in] chart the chart
 * \param[in] png_path the PNG file
 * \param[in] width_px image width, px, > 0
 * \param[in] height_px image height, px, > 0
 * \throws planar_grid::Exception for a series whose x and y differ in size, a
 *         non-finite value, y <= 0 on a log axis, a non-positive size, or no X display
 *         (Debian's VTK 9.1 renders offscreen only through an X server; see
 *         ensureDisplay()); planar_grid::IOError when the file cannot be written (its
 *         folder is missing, ...), leaving no file behind
 * \ingroup visualization */
void saveLineChart(const LineChart& chart,
                   const std::string& png_path,
                   int width_px = 900,
                   int height_px = 600);

} // namespace planar_grid
