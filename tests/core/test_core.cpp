// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/counting_sort.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/stereo_calibration.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace {

namespace fs = std::filesystem;

/** \brief The Karlsruhe calibration (data README: f from P1_roi, B = 368.2632 / f). */
planar_grid::StereoCalibration
karlsruheCalibration()
{
  planar_grid::StereoCalibration calibration;
  calibration.focal_length_px = 645.2401;
  calibration.cx_px = 635.9587;
  calibration.cy_px = 194.1291;
  calibration.baseline_m = 0.5707;
  calibration.width = 1344;
  calibration.height = 372;
  return calibration;
}

std::string
readAll(const fs::path& path)
{
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in),
                     std::istreambuf_iterator<char>());
}

/** \brief A fresh, empty folder per test, removed afterwards. */
class AtomicFileTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_test_core_" + std::string(info->name()) + "_"
              + std::to_string(static_cast<long>(::getpid())));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override
  {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  /** \brief Number of entries in the test folder (to spot leftover temporary files). */
  std::size_t entries() const
  {
    return static_cast<std::size_t>(
      std::distance(fs::directory_iterator(dir_), fs::directory_iterator()));
  }
  /** \brief Writes \a content to \a path directly (the "existing file"). */
  static void writePlain(const fs::path& path, const std::string& content)
  {
    std::ofstream out(path, std::ios::binary);
    out << content;
  }

  /** \brief The test's own folder. */
  fs::path dir_;
};

} // namespace

// ---------------------------------------------------------------- StereoCalibration

TEST(StereoCalibration, ValidateAcceptsKarlsruhe)
{
  EXPECT_NO_THROW(karlsruheCalibration().validate("calib.txt"));
}

TEST(StereoCalibration, ValidateRejectsBadValuesNamingSource)
{
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto expectRejected = [](const planar_grid::StereoCalibration& calibration) {
    try {
      calibration.validate("my_calib.txt");
      ADD_FAILURE() << "validate() accepted an invalid calibration";
    } catch (const planar_grid::IOError& e) {
      EXPECT_NE(std::string(e.what()).find("my_calib.txt"), std::string::npos)
        << e.what();
    }
  };
  planar_grid::StereoCalibration calibration = karlsruheCalibration();
  calibration.focal_length_px = 0.0;
  expectRejected(calibration);
  calibration = karlsruheCalibration();
  calibration.focal_length_px = nan;
  expectRejected(calibration);
  calibration = karlsruheCalibration();
  calibration.baseline_m = -0.5707;
  expectRejected(calibration);
  calibration = karlsruheCalibration();
  calibration.baseline_m = std::numeric_limits<double>::infinity();
  expectRejected(calibration);
  // Outside what stereo rigs have: millimetres taken for metres, or a corrupt value.
  for (const double baseline : {1e6, 570.7, 0.9e-3}) {
    calibration = karlsruheCalibration();
    calibration.baseline_m = baseline;
    expectRejected(calibration);
  }
  for (const double baseline : {1e-3, 100.0}) {
    calibration = karlsruheCalibration();
    calibration.baseline_m = baseline;
    EXPECT_NO_THROW(calibration.validate("my_calib.txt")) << baseline;
  }
  calibration = karlsruheCalibration();
  calibration.cx_px = nan;
  expectRejected(calibration);
  calibration = karlsruheCalibration();
  calibration.height = -1;
  expectRejected(calibration);
  // A default-constructed calibration (f = B = 0) is invalid too.
  expectRejected(planar_grid::StereoCalibration{});
}

TEST(StereoCalibration, DepthFromDisparityKarlsruhe)
{
  const planar_grid::StereoCalibration calibration = karlsruheCalibration();
  // z = f B / d = 645.2401 * 0.5707 / 10 = 368.23852507 / 10 = 36.823852507 m.
  // Tolerance 1e-9 m: one multiplication and one division in double precision.
  EXPECT_NEAR(calibration.depthFromDisparity(10.0), 36.823852507, 1e-9);
  // Halving the disparity doubles the depth.
  EXPECT_NEAR(calibration.depthFromDisparity(5.0), 2.0 * 36.823852507, 1e-9);
  // No disparity (or a negative, invalid one) is a point at infinity.
  EXPECT_TRUE(std::isinf(calibration.depthFromDisparity(0.0)));
  EXPECT_TRUE(std::isinf(calibration.depthFromDisparity(-1.0)));
}

TEST(StereoCalibration, DepthErrorKarlsruhe)
{
  const planar_grid::StereoCalibration calibration = karlsruheCalibration();
  // dz = z^2 / (B f) * dd = 100 / (0.5707 * 645.2401) * 0.5 = 0.135781556 m at z = 10
  // m. Tolerance 1e-9 m: a handful of double operations on numbers near 1.
  const double expected = 100.0 / (0.5707 * 645.2401) * 0.5;
  EXPECT_NEAR(expected, 0.135781556, 1e-9);
  EXPECT_NEAR(calibration.depthError(10.0, 0.5), expected, 1e-12);
  // The default disparity error is 0.5 px.
  EXPECT_NEAR(calibration.depthError(10.0), expected, 1e-12);
  // Quadratic in depth: 4x the error at twice the distance.
  EXPECT_NEAR(calibration.depthError(20.0, 0.5), 4.0 * expected, 1e-12);
}

// ---------------------------------------------------------------- ConfigError

TEST(ConfigError, WhatIsFileLineColumnMessage)
{
  const planar_grid::ConfigError error("config/karlsruhe.yaml", 12, 5,
                                       "unknown key 'foo'");
  EXPECT_STREQ(error.what(), "config/karlsruhe.yaml:12:5: unknown key 'foo'");
  EXPECT_EQ(error.file(), "config/karlsruhe.yaml");
  EXPECT_EQ(error.line(), 12);
  EXPECT_EQ(error.column(), 5);
}

TEST(ConfigError, UnknownPartsAreOmitted)
{
  EXPECT_STREQ(planar_grid::ConfigError("a.yaml", 3, 0, "bad").what(), "a.yaml:3: bad");
  EXPECT_STREQ(planar_grid::ConfigError("a.yaml", 0, 0, "bad").what(), "a.yaml: bad");
  EXPECT_STREQ(planar_grid::ConfigError("", 2, 1, "bad").what(), "<yaml>:2:1: bad");
}

TEST(ConfigError, IsAPlanarGridException)
{
  try {
    throw planar_grid::ConfigError("a.yaml", 1, 1, "bad");
  } catch (const planar_grid::Exception& e) {
    EXPECT_STREQ(e.what(), "a.yaml:1:1: bad");
    return;
  }
  ADD_FAILURE() << "ConfigError was not caught as planar_grid::Exception";
}

// ---------------------------------------------------------------- atomic files

TEST_F(AtomicFileTest, SuccessWritesTheFile)
{
  const fs::path target = dir_ / "out.txt";
  planar_grid::writeTextFileAtomically(target.string(), "hello\n");
  EXPECT_EQ(readAll(target), "hello\n");
  EXPECT_EQ(entries(), 1u); // only the target, no temporary file left
  // Replacing an existing file works too.
  planar_grid::writeTextFileAtomically(target.string(), "world\n");
  EXPECT_EQ(readAll(target), "world\n");
  EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicFileTest, WriterReturningFalseLeavesExistingFile)
{
  const fs::path target = dir_ / "out.txt";
  writePlain(target, "old");
  EXPECT_THROW(planar_grid::writeFileAtomically(target.string(),
                                                [](const std::string& tmp) {
                                                  std::ofstream(tmp) << "half";
                                                  return false;
                                                }),
               planar_grid::IOError);
  EXPECT_EQ(readAll(target), "old");
  EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicFileTest, WriterThrowingLeavesExistingFile)
{
  const fs::path target = dir_ / "out.txt";
  writePlain(target, "old");
  EXPECT_THROW(planar_grid::writeFileAtomically(target.string(),
                                                [](const std::string& tmp) -> bool {
                                                  std::ofstream(tmp) << "half";
                                                  throw std::runtime_error(
                                                    "disk on fire");
                                                }),
               std::runtime_error);
  EXPECT_EQ(readAll(target), "old");
  EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicFileTest, WriterThatWritesNothingFails)
{
  const fs::path target = dir_ / "out.txt";
  EXPECT_THROW(planar_grid::writeFileAtomically(
                 target.string(), [](const std::string&) { return true; }),
               planar_grid::IOError);
  EXPECT_FALSE(fs::exists(target));
  EXPECT_EQ(entries(), 0u);
}

TEST_F(AtomicFileTest, FolderAsTheTargetIsRefusedBeforeTheWrite)
{
  // The writer is not called: a large output is not written only to be thrown away.
  const fs::path folder = dir_ / "map.pgmap";
  fs::create_directory(folder);
  bool called = false;
  try {
    planar_grid::writeFileAtomically(folder.string(), [&called](const std::string&) {
      called = true;
      return true;
    });
    ADD_FAILURE() << "a folder was accepted as the file to write";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(
      std::string(e.what()).find(folder.string() + ": cannot write: it is a folder"),
      std::string::npos)
      << e.what();
  }
  EXPECT_FALSE(called);
  EXPECT_TRUE(fs::is_directory(folder));
  EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicFileTest, MissingFolderThrowsNamingIt)
{
  const fs::path missing = dir_ / "no_such_folder";
  const fs::path target = missing / "out.txt";
  try {
    planar_grid::writeTextFileAtomically(target.string(), "x");
    ADD_FAILURE() << "no exception for a missing folder";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos)
      << e.what();
  }
  EXPECT_FALSE(fs::exists(missing));
}

TEST(StereoCalibration, APrincipalPointFarFromTheCentreIsWarnedAbout)
{
  // Karlsruhe's calib.txt: P1_roi is the calibration of the cropped 1344 x 372 px
  // images, P1 that of the full ones (cy 264 px: 21 % of the height below the centre).
  const planar_grid::StereoCalibration roi = karlsruheCalibration();
  EXPECT_EQ(roi.principalPointWarning(1344, 372, "calib.txt"), "");
  planar_grid::StereoCalibration full = roi;
  full.cx_px = 661.9587;
  full.cy_px = 264.1291;
  const std::string warning = full.principalPointWarning(1344, 372, "calib.txt");
  EXPECT_NE(warning.find("calib.txt: the principal point (662, 264.1) px lies 21 % of "
                         "the image's height"),
            std::string::npos)
    << warning;
  // A column off the centre by more than 15 % of the width too; no size: no judgement.
  planar_grid::StereoCalibration left = roi;
  left.cx_px = 400.0;
  EXPECT_NE(left.principalPointWarning(1344, 372, "c").find("width"),
            std::string::npos);
  EXPECT_EQ(full.principalPointWarning(0, 0, "c"), "");
}

TEST(CountingSort, EqualsAStableSortByBucketWithoutTheItemsOutOfRange)
{
  std::mt19937 rng(7);
  for (const std::size_t n_buckets :
       {std::size_t{1}, std::size_t{5}, std::size_t{64}}) {
    // buckets n_buckets and n_buckets + 1 are out of range: those items are left out
    std::uniform_int_distribution<std::uint32_t> bucket(
      0, static_cast<std::uint32_t>(n_buckets + 1));
    for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{300}}) {
      std::vector<std::uint32_t> bucket_of(n);
      for (auto& b : bucket_of)
        b = bucket(rng);
      std::vector<std::uint32_t> expected;
      for (std::uint32_t i = 0; i < n; ++i)
        if (bucket_of[i] < n_buckets)
          expected.push_back(i);
      std::stable_sort(
        expected.begin(), expected.end(),
        [&](std::uint32_t a, std::uint32_t b) { return bucket_of[a] < bucket_of[b]; });
      std::vector<std::uint32_t> begin, order;
      planar_grid::countingSort(bucket_of, n_buckets, begin, order);
      EXPECT_EQ(order, expected) << n_buckets << " buckets, " << n << " items";
      ASSERT_EQ(begin.size(), n_buckets + 1);
      EXPECT_EQ(begin.front(), 0u);
      EXPECT_EQ(begin.back(), expected.size());
      for (std::size_t b = 0; b < n_buckets; ++b)
        for (std::uint32_t k = begin[b]; k < begin[b + 1]; ++k)
          EXPECT_EQ(bucket_of[order[k]], b);
    }
  }
}
