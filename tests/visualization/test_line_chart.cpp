// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/line_chart.h>
#include <planar_grid/visualization/scene_renderer.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;

/** \brief Four methods over the paper's cell sizes 0.1-0.5 m (Fig. 14-like numbers). */
planar_grid::LineChart
memoryChart()
{
  planar_grid::LineChart chart;
  chart.title = "Memory against cell size";
  chart.x_label = "minimum cell size [m]";
  chart.y_label = "memory [MB]";
  const std::vector<double> sizes{0.1, 0.2, 0.3, 0.4, 0.5};
  chart.series.push_back({"PG", sizes, {2.0, 1.1, 0.8, 0.6, 0.5}});
  chart.series.push_back({"RA", sizes, {4.0, 2.2, 1.5, 1.2, 1.0}});
  chart.series.push_back({"SG", sizes, {12.0, 3.0, 1.4, 0.8, 0.5}});
  chart.series.push_back({"OG", sizes, {7.0, 2.5, 1.2, 0.9, 0.7}});
  return chart;
}

/** \brief Pixels of \a image (BGR) within 40 of the colour (r, g, b). */
int
countColour(const cv::Mat& image, int r, int g, int b)
{
  int count = 0;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
      count +=
        std::abs(p[2] - r) < 40 && std::abs(p[1] - g) < 40 && std::abs(p[0] - b) < 40;
    }
  return count;
}

class LineChartTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    if (!planar_grid::hasDisplay())
      GTEST_SKIP() << "no X display; run under xvfb-run -a";
    dir_ = fs::temp_directory_path()
           / (std::string("planar_grid_test_chart_")
              + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"
              + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }

  void TearDown() override
  {
    std::error_code ec;
    if (!dir_.empty())
      fs::remove_all(dir_, ec);
  }

  /** \brief A per-test folder, removed afterwards. */
  fs::path dir_;
};

TEST_F(LineChartTest, WritesPNGOfRequestedSizeWithOneColouredLinePerSeries)
{
  const std::string path = (dir_ / "memory.png").string();
  planar_grid::saveLineChart(memoryChart(), path, 640, 480);
  const cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
  // White background with axes, text and lines on it.
  int non_white = 0;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
      non_white += (p[0] < 200 || p[1] < 200 || p[2] < 200) ? 1 : 0;
    }
  EXPECT_GT(non_white, 640 * 480 / 100);
  EXPECT_LT(non_white, 640 * 480 / 2);
  // Each line in its own colour (the first four of the Tableau palette): blue,
  // orange, green, red; a line with markers across the plot covers > 300 px.
  EXPECT_GT(countColour(image, 31, 119, 180), 300);
  EXPECT_GT(countColour(image, 255, 127, 14), 300);
  EXPECT_GT(countColour(image, 44, 160, 44), 300);
  EXPECT_GT(countColour(image, 214, 39, 40), 300);
}

TEST_F(LineChartTest, LogAxisAndEmptyChartRender)
{
  planar_grid::LineChart chart = memoryChart();
  chart.log_y = true;
  const std::string log_path = (dir_ / "log.png").string();
  planar_grid::saveLineChart(chart, log_path, 320, 240);
  const cv::Mat image = cv::imread(log_path, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 320);
  EXPECT_EQ(image.rows, 240);

  const std::string empty_path = (dir_ / "empty.png").string();
  planar_grid::saveLineChart(planar_grid::LineChart(), empty_path, 200, 100);
  EXPECT_EQ(cv::imread(empty_path).cols, 200);
}

TEST_F(LineChartTest, MissingFolderThrowsIOErrorAndLeavesNothing)
{
  const fs::path path = dir_ / "missing" / "chart.png";
  EXPECT_THROW(planar_grid::saveLineChart(memoryChart(), path.string()),
               planar_grid::IOError);
  EXPECT_FALSE(fs::exists(path));
}

TEST(LineChart, InvalidSeriesThrowBeforeRendering)
{
  // Checked before any rendering, so these need no display.
  const std::string path =
    (fs::temp_directory_path()
     / ("planar_grid_never_" + std::to_string(::getpid()) + ".png"))
      .string();
  planar_grid::LineChart mismatched = memoryChart();
  mismatched.series[1].y.pop_back();
  EXPECT_THROW(planar_grid::saveLineChart(mismatched, path), planar_grid::Exception);

  planar_grid::LineChart not_finite = memoryChart();
  not_finite.series[0].x[2] = std::nan("");
  EXPECT_THROW(planar_grid::saveLineChart(not_finite, path), planar_grid::Exception);

  planar_grid::LineChart log_of_zero = memoryChart();
  log_of_zero.log_y = true;
  log_of_zero.series[3].y[0] = 0.0;
  EXPECT_THROW(planar_grid::saveLineChart(log_of_zero, path), planar_grid::Exception);

  EXPECT_THROW(planar_grid::saveLineChart(memoryChart(), path, 0, 100),
               planar_grid::Exception);
  EXPECT_FALSE(fs::exists(path));
}

} // namespace
