// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/line_chart.h>
#include <planar_grid/visualization/scene_renderer.h>

#include <vtkAxis.h>
#include <vtkChartLegend.h>
#include <vtkChartXY.h>
#include <vtkContextScene.h>
#include <vtkContextView.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPlotLine.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkTable.h>
#include <vtkTextProperty.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "render_window_png.h"

namespace planar_grid {

namespace {

/** \brief Line colours in turn (Tableau 10): blue, orange, green, red, purple, brown,
 * pink, grey, olive, cyan. */
constexpr std::array<std::array<unsigned char, 3>, 10> PALETTE{{{31, 119, 180},
                                                                {255, 127, 14},
                                                                {44, 160, 44},
                                                                {214, 39, 40},
                                                                {148, 103, 189},
                                                                {140, 86, 75},
                                                                {227, 119, 194},
                                                                {127, 127, 127},
                                                                {188, 189, 34},
                                                                {23, 190, 207}}};

/** \brief Markers in turn, so that lines stay apart in grey print. */
constexpr std::array<int, 5> MARKERS{vtkPlotPoints::CIRCLE, vtkPlotPoints::SQUARE,
                                     vtkPlotPoints::DIAMOND, vtkPlotPoints::CROSS,
                                     vtkPlotPoints::PLUS};

/** \brief Space left on each side of the data along each axis, as a fraction of the
 * data's span. */
constexpr double AXIS_MARGIN = 0.04;

/** \brief Throws planar_grid::Exception for a series that cannot be drawn. */
void
validate(const LineChart& chart, int width_px, int height_px)
{
  const std::string where = "[planar_grid::saveLineChart] ";
  if (width_px <= 0 || height_px <= 0)
    throw Exception(where + "image size must be positive, got "
                    + std::to_string(width_px) + "x" + std::to_string(height_px));
  for (const auto& series : chart.series) {
    if (series.x.size() != series.y.size())
      throw Exception(where + "series '" + series.name + "' has "
                      + std::to_string(series.x.size()) + " x values but "
                      + std::to_string(series.y.size()) + " y values");
    for (std::size_t i = 0; i < series.x.size(); ++i) {
      if (!std::isfinite(series.x[i]) || !std::isfinite(series.y[i]))
        throw Exception(where + "series '" + series.name
                        + "' has a non-finite value at " + std::to_string(i));
      if (chart.log_y && !(series.y[i] > 0.0))
        throw Exception(where + "series '" + series.name
                        + "' has y = " + std::to_string(series.y[i]) + " <= 0 at "
                        + std::to_string(i) + " on a logarithmic axis");
    }
  }
}

} // namespace

void
saveLineChart(const LineChart& chart,
              const std::string& png_path,
              int width_px,
              int height_px)
{
  validate(chart, width_px, height_px);
  if (!hasDisplay())
    throw Exception(
      "cannot save " + png_path
      + ": no X display: VTK 9.1 from Debian renders offscreen only "
        "through an X server; install xvfb (apt-get install xvfb) and run "
        "under `xvfb-run -a <command>`");

  vtkNew<vtkChartXY> xy;
  xy->SetTitle(chart.title);
  xy->GetTitleProperties()->SetFontSize(18);
  xy->GetTitleProperties()->SetColor(0.0, 0.0, 0.0);
  vtkAxis* bottom = xy->GetAxis(vtkAxis::BOTTOM);
  vtkAxis* left = xy->GetAxis(vtkAxis::LEFT);
  bottom->SetTitle(chart.x_label);
  left->SetTitle(chart.y_label);
  for (vtkAxis* axis : {bottom, left}) {
    axis->GetTitleProperties()->SetFontSize(15);
    axis->GetTitleProperties()->SetBold(false);
    axis->GetLabelProperties()->SetFontSize(13);
    axis->SetGridVisible(true);
  }
  left->SetLogScale(chart.log_y);

  // Fixed ranges a little wider than the data, so that the markers on the first and
  // last values are not cut in half by the plot's edges.
  double x_min = std::numeric_limits<double>::infinity(), x_max = -x_min;
  double y_min = x_min, y_max = -x_min;
  for (const auto& series : chart.series)
    for (std::size_t i = 0; i < series.x.size(); ++i) {
      x_min = std::min(x_min, series.x[i]);
      x_max = std::max(x_max, series.x[i]);
      y_min = std::min(y_min, series.y[i]);
      y_max = std::max(y_max, series.y[i]);
    }
  if (x_min <= x_max) {
    const auto padded = [](double lo, double hi, double& out_lo, double& out_hi) {
      const double span = hi > lo ? hi - lo : std::max(std::abs(lo), 1.0);
      out_lo = lo - AXIS_MARGIN * span;
      out_hi = hi + AXIS_MARGIN * span;
    };
    double lo = 0.0, hi = 0.0;
    padded(x_min, x_max, lo, hi);
    bottom->SetBehavior(vtkAxis::FIXED);
    bottom->SetUnscaledRange(lo, hi);
    if (chart.log_y) {
      // The same margin in decades.
      padded(std::log10(y_min), std::log10(y_max), lo, hi);
      lo = std::pow(10.0, lo);
      hi = std::pow(10.0, hi);
    } else
      padded(y_min, y_max, lo, hi);
    left->SetBehavior(vtkAxis::FIXED);
    left->SetUnscaledRange(lo, hi);
  }

  for (std::size_t k = 0; k < chart.series.size(); ++k) {
    const LineSeries& series = chart.series[k];
    vtkNew<vtkTable> table;
    vtkNew<vtkDoubleArray> x;
    x->SetName("x");
    vtkNew<vtkDoubleArray> y;
    // Column names must differ within the table only; the legend shows the label.
    y->SetName("y");
    const auto n = static_cast<vtkIdType>(series.x.size());
    x->SetNumberOfValues(n);
    y->SetNumberOfValues(n);
    for (vtkIdType i = 0; i < n; ++i) {
      x->SetValue(i, series.x[static_cast<std::size_t>(i)]);
      y->SetValue(i, series.y[static_cast<std::size_t>(i)]);
    }
    table->AddColumn(x);
    table->AddColumn(y);

    vtkNew<vtkPlotLine> line;
    line->SetInputData(table, 0, 1);
    line->SetLabel(series.name);
    const auto& colour = PALETTE[k % PALETTE.size()];
    line->SetColor(colour[0], colour[1], colour[2], 255);
    line->SetWidth(2.5f);
    line->SetMarkerStyle(MARKERS[k % MARKERS.size()]);
    line->SetMarkerSize(9.0f);
    xy->AddPlot(line);
  }
  xy->SetShowLegend(!chart.series.empty());
  vtkChartLegend* legend = xy->GetLegend();
  legend->SetHorizontalAlignment(vtkChartLegend::RIGHT);
  legend->SetVerticalAlignment(vtkChartLegend::TOP);
  legend->SetLabelSize(14);

  vtkNew<vtkContextView> view;
  view->GetRenderer()->SetBackground(1.0, 1.0, 1.0);
  vtkRenderWindow* window = view->GetRenderWindow();
  window->SetOffScreenRendering(1);
  window->SetMultiSamples(0);
  window->SetSize(width_px, height_px);
  view->GetScene()->AddItem(xy);
  try {
    detail::saveRenderWindowPng(window, png_path);
  } catch (...) {
    window->Finalize();
    throw;
  }
  window->Finalize();
}

} // namespace planar_grid
