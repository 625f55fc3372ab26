// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/rectangle_merge.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <vector>

namespace {

using planar_grid::rasterCellI;
using planar_grid::rasterCellJ;
using planar_grid::rasterCellKey;
using planar_grid::RasterRectangle;
using planar_grid::RectangleMergeRule;

/** A sparse raster: sorted keys and the class (0 / 1) of each. */
struct Raster {
  std::vector<std::uint64_t> keys;
  std::vector<std::uint8_t> classes;
  std::map<std::uint64_t, int> cls; // key -> class

  int at(std::int64_t i, std::int64_t j) const
  {
    const auto it = cls.find(
      rasterCellKey(static_cast<std::int32_t>(i), static_cast<std::int32_t>(j)));
    return it == cls.end() ? -1 : it->second;
  }
};

/** A random raster of \a w x \a h cells at (i0, j0), each cell present with
 * probability \a density, of class 1 with probability 0.5 when \a two_classes (else
 * all 0). */
Raster
randomRaster(std::mt19937& rng,
             int i0,
             int j0,
             int w,
             int h,
             float density,
             bool two_classes)
{
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  Raster r;
  for (int j = j0; j < j0 + h; ++j)
    for (int i = i0; i < i0 + w; ++i) {
      if (!(uni(rng) < density))
        continue;
      const std::uint8_t c = two_classes && uni(rng) < 0.5f ? 1 : 0;
      r.keys.push_back(rasterCellKey(i, j));
      r.classes.push_back(c);
      r.cls[r.keys.back()] = c;
    }
  return r;
}

/** Every raster cell lies in exactly one rectangle, the rectangles hold no other
 * cell and each holds one class. */
void
expectExactPartition(const Raster& r, const std::vector<RasterRectangle>& rects)
{
  std::map<std::uint64_t, int> hits;
  for (const RasterRectangle& rect : rects) {
    ASSERT_LT(rect.i0, rect.i1);
    ASSERT_LT(rect.j0, rect.j1);
    const int c = r.at(rect.i0, rect.j0);
    for (std::int32_t j = rect.j0; j < rect.j1; ++j)
      for (std::int32_t i = rect.i0; i < rect.i1; ++i) {
        ASSERT_GE(r.at(i, j), 0) << "cell " << i << " " << j << " is not in the raster";
        EXPECT_EQ(r.at(i, j), c) << "two classes in one rectangle";
        ++hits[rasterCellKey(i, j)];
      }
  }
  ASSERT_EQ(hits.size(), r.keys.size());
  for (const auto& kv : hits)
    EXPECT_EQ(kv.second, 1);
}

/** Brute force: the fewest rectangles partitioning the cells of \a mask (bit y * w +
 * x, w * h <= 20) whose class bits in \a cls agree within each rectangle. The first
 * free cell in row-major order is the lower-left corner of its rectangle: try every
 * width and height from it (memoised on the set of free cells). */
int
fewestRectangles(std::uint32_t mask,
                 std::uint32_t cls,
                 int w,
                 int h,
                 std::vector<int>& memo)
{
  if (mask == 0)
    return 0;
  if (memo[mask] >= 0)
    return memo[mask];
  int first = 0;
  while ((mask & (1u << first)) == 0)
    ++first;
  const int x0 = first % w, y0 = first / w;
  const std::uint32_t c = (cls >> first) & 1u;
  const auto bit = [w](int x, int y) {
    return 1u << (y * w + x);
  };
  int best = std::numeric_limits<int>::max();
  for (int x1 = x0 + 1; x1 <= w; ++x1) {
    bool row_ok = true;
    for (int x = x0; x < x1; ++x)
      row_ok = row_ok && (mask & bit(x, y0)) != 0 && ((cls >> (y0 * w + x)) & 1u) == c;
    if (!row_ok)
      break;
    std::uint32_t taken = 0;
    for (int y1 = y0 + 1; y1 <= h; ++y1) {
      bool ok = true;
      for (int x = x0; x < x1; ++x)
        ok =
          ok && (mask & bit(x, y1 - 1)) != 0 && ((cls >> ((y1 - 1) * w + x)) & 1u) == c;
      if (!ok)
        break;
      for (int x = x0; x < x1; ++x)
        taken |= bit(x, y1 - 1);
      best = std::min(best, 1 + fewestRectangles(mask & ~taken, cls, w, h, memo));
    }
  }
  memo[mask] = best;
  return best;
}

} // namespace

// Oracle: closeRasterGaps() against a cell-by-cell search on random rasters (14 x 11
// cells at negative and positive indices, densities 0.2-0.8, max_gap 0-3): a cell
// outside the raster is filled exactly when, in its row or in its column, raster
// cells lie on both sides with at most max_gap cells from one to the other.
TEST(RectangleMerge, CloseGapsMatchesBruteForce)
{
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  for (int trial = 0; trial < 60; ++trial) {
    const int max_gap = trial % 4;
    const Raster r = randomRaster(rng, -6, -4, 14, 11, 0.2f + 0.6f * uni(rng), false);
    const std::vector<std::uint64_t> filled =
      planar_grid::closeRasterGaps(r.keys, max_gap);
    std::vector<std::uint64_t> expected;
    for (int j = -6; j < 9; ++j)
      for (int i = -8; i < 10; ++i) {
        if (r.at(i, j) >= 0)
          continue;
        bool fill = false;
        // (di, dj) in {(1, 0), (0, 1)}: the nearest raster cells on both sides
        for (const auto& step : {std::make_pair(1, 0), std::make_pair(0, 1)}) {
          int before = 1, after = 1;
          while (before <= max_gap + 1
                 && r.at(i - before * step.first, j - before * step.second) < 0)
            ++before;
          while (after <= max_gap + 1
                 && r.at(i + after * step.first, j + after * step.second) < 0)
            ++after;
          // the gap holds before + after - 1 cells
          fill = fill
                 || (before <= max_gap + 1 && after <= max_gap + 1
                     && before + after - 1 <= max_gap);
        }
        if (fill)
          expected.push_back(rasterCellKey(i, j));
      }
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(filled, expected) << "trial " << trial << " max_gap " << max_gap;
  }
  EXPECT_TRUE(planar_grid::closeRasterGaps({}, 2).empty());
}

// Oracle: the paper's rule (Fig. 6b) on random rasters (20 x 12 cells, one or two
// classes) is the unique cover with these properties: an exact partition into
// rectangles of one class, each row of a rectangle a maximal run of its class (the
// cells left and right of it are not of that class), and no two rectangles of one
// class with equal [i0, i1) stacked directly on each other (they would be one).
TEST(RectangleMerge, PaperRuleIsFig6MaximalRunsStacked)
{
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  for (int trial = 0; trial < 60; ++trial) {
    const Raster r =
      randomRaster(rng, -3, 2, 20, 12, 0.5f + 0.5f * uni(rng), trial % 2 == 1);
    const std::vector<RasterRectangle> rects =
      planar_grid::mergeRasterRectangles(r.keys, r.classes, RectangleMergeRule::PAPER);
    expectExactPartition(r, rects);
    for (const RasterRectangle& a : rects) {
      const int c = r.at(a.i0, a.j0);
      for (std::int32_t j = a.j0; j < a.j1; ++j) {
        EXPECT_NE(r.at(a.i0 - 1, j), c) << "run not maximal, trial " << trial;
        EXPECT_NE(r.at(a.i1, j), c) << "run not maximal, trial " << trial;
      }
      for (const RasterRectangle& b : rects)
        EXPECT_FALSE(b.i0 == a.i0 && b.i1 == a.i1 && b.j0 == a.j1
                     && r.at(b.i0, b.j0) == c)
          << "equal runs not stacked, trial " << trial;
    }
    // listed by first row, then first column
    for (std::size_t k = 1; k < rects.size(); ++k)
      EXPECT_TRUE(rects[k - 1].j0 < rects[k].j0
                  || (rects[k - 1].j0 == rects[k].j0 && rects[k - 1].i0 < rects[k].i0));
  }
}

// Oracle: on 300 random 5 x 4 rasters (any density, one or two classes),
// MIN_RECTANGLES gives an exact partition with exactly the fewest rectangles of a
// brute-force search, never more than the paper's rule.
TEST(RectangleMerge, MinRectanglesIsTheMinimumPartition)
{
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  const int w = 5, h = 4;
  std::size_t optimum_total = 0, paper_total = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Raster r =
      randomRaster(rng, 0, 0, w, h, 0.4f + 0.6f * uni(rng), trial % 3 == 0);
    std::uint32_t mask = 0, cls = 0;
    for (std::size_t k = 0; k < r.keys.size(); ++k) {
      const int bit = rasterCellJ(r.keys[k]) * w + rasterCellI(r.keys[k]);
      mask |= 1u << bit;
      cls |= static_cast<std::uint32_t>(r.classes[k]) << bit;
    }
    std::vector<int> memo(1u << (w * h), -1);
    const int optimum = fewestRectangles(mask, cls, w, h, memo);
    const auto fewest = planar_grid::mergeRasterRectangles(
      r.keys, r.classes, RectangleMergeRule::MIN_RECTANGLES);
    const auto paper =
      planar_grid::mergeRasterRectangles(r.keys, r.classes, RectangleMergeRule::PAPER);
    expectExactPartition(r, fewest);
    EXPECT_EQ(fewest.size(), static_cast<std::size_t>(optimum)) << "trial " << trial;
    EXPECT_GE(paper.size(), fewest.size());
    optimum_total += static_cast<std::size_t>(optimum);
    paper_total += paper.size();
  }
  std::printf("5 x 4 rasters: fewest rectangles %zu in all, the paper's rule %zu\n",
              optimum_total, paper_total);
  EXPECT_LT(optimum_total, paper_total);
}

// Oracle: the DENSITY cover on random rasters (24 x 16 cells, one or two classes) at
// D = 0.9 and 1: every raster cell in exactly one rectangle, rectangles disjoint, at
// least D of each rectangle's cells of one class; at D = 1 an exact partition. At D =
// 0.9 it needs fewer rectangles than MIN_RECTANGLES in all.
TEST(RectangleMerge, DensityCoverHoldsTheRasterAtItsDensity)
{
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  std::size_t density_total = 0, fewest_total = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Raster r =
      randomRaster(rng, -10, -5, 24, 16, 0.5f + 0.45f * uni(rng), trial % 2 == 1);
    for (const double d : {0.9, 1.0}) {
      const auto rects = planar_grid::mergeRasterRectangles(
        r.keys, r.classes, RectangleMergeRule::DENSITY, d);
      if (d == 1.0) {
        expectExactPartition(r, rects);
        continue;
      }
      std::map<std::uint64_t, int> hits;
      for (const RasterRectangle& rect : rects) {
        // the seed (the rectangle's class) need not be its lower-left cell: the
        // rectangle grows to all sides
        std::int64_t of_class[2] = {0, 0}, area = 0;
        for (std::int32_t j = rect.j0; j < rect.j1; ++j)
          for (std::int32_t i = rect.i0; i < rect.i1; ++i) {
            ++area;
            const int c = r.at(i, j);
            if (c >= 0)
              ++of_class[c];
            EXPECT_EQ(++hits[rasterCellKey(i, j)], 1) << "rectangles overlap";
          }
        EXPECT_GE(static_cast<double>(std::max(of_class[0], of_class[1])),
                  d * static_cast<double>(area) - 1e-9)
          << "trial " << trial;
      }
      for (const auto key : r.keys)
        EXPECT_EQ(hits.count(key), 1u);
      density_total += rects.size();
      fewest_total += planar_grid::mergeRasterRectangles(
                        r.keys, r.classes, RectangleMergeRule::MIN_RECTANGLES)
                        .size();
    }
  }
  std::printf("density 0.9: %zu rectangles, min_rectangles %zu\n", density_total,
              fewest_total);
  EXPECT_LT(density_total, fewest_total);
}

// Oracle: the DENSITY cover leaves no two rectangles that could be one. On random
// rasters (20 x 14 cells, one or two classes) at D = 0.7 and 0.9, for every pair of
// edge-adjacent rectangles, their bounding box U is not a valid rectangle of the
// cover: it holds a cell of another 4-connected component, or cuts a third rectangle,
// or fewer than D of its cells are of one class. Brute force over all pairs.
TEST(RectangleMerge, DensityCoverLeavesNoTwoRectanglesThatCouldBeOne)
{
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  std::size_t pairs = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const Raster r =
      randomRaster(rng, 3, -7, 20, 14, 0.6f + 0.35f * uni(rng), trial % 2 == 1);
    // 4-connected components by flood fill
    std::map<std::uint64_t, int> component;
    int components = 0;
    for (const auto key : r.keys) {
      if (component.count(key))
        continue;
      std::vector<std::uint64_t> todo{key};
      component[key] = components;
      while (!todo.empty()) {
        const std::uint64_t k = todo.back();
        todo.pop_back();
        const std::int32_t i = rasterCellI(k), j = rasterCellJ(k);
        for (const auto& d : {std::pair<int, int>{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
          const std::uint64_t n = rasterCellKey(i + d.first, j + d.second);
          if (r.cls.count(n) && !component.count(n)) {
            component[n] = components;
            todo.push_back(n);
          }
        }
      }
      ++components;
    }
    for (const double d : {0.7, 0.9}) {
      const auto rects = planar_grid::mergeRasterRectangles(
        r.keys, r.classes, RectangleMergeRule::DENSITY, d);
      std::map<std::uint64_t, std::size_t> owner;
      for (std::size_t k = 0; k < rects.size(); ++k)
        for (std::int32_t j = rects[k].j0; j < rects[k].j1; ++j)
          for (std::int32_t i = rects[k].i0; i < rects[k].i1; ++i)
            ASSERT_TRUE(owner.emplace(rasterCellKey(i, j), k).second)
              << "rectangles overlap";
      const auto touch = [](const RasterRectangle& a, const RasterRectangle& b) {
        const bool rows = a.j0 < b.j1 && b.j0 < a.j1;
        const bool cols = a.i0 < b.i1 && b.i0 < a.i1;
        return (rows && (a.i1 == b.i0 || b.i1 == a.i0))
               || (cols && (a.j1 == b.j0 || b.j1 == a.j0));
      };
      for (std::size_t a = 0; a < rects.size(); ++a)
        for (std::size_t b = a + 1; b < rects.size(); ++b) {
          if (!touch(rects[a], rects[b]))
            continue;
          ++pairs;
          const RasterRectangle u{
            std::min(rects[a].i0, rects[b].i0), std::max(rects[a].i1, rects[b].i1),
            std::min(rects[a].j0, rects[b].j0), std::max(rects[a].j1, rects[b].j1)};
          // every rectangle holds a raster cell; its component is the pair's
          int own_component = -1;
          for (std::int32_t j = rects[a].j0; j < rects[a].j1 && own_component < 0; ++j)
            for (std::int32_t i = rects[a].i0; i < rects[a].i1; ++i)
              if (r.at(i, j) >= 0) {
                own_component = component.at(rasterCellKey(i, j));
                break;
              }
          ASSERT_GE(own_component, 0);
          bool valid = true;
          std::int64_t of_class[2] = {0, 0};
          for (std::int32_t j = u.j0; j < u.j1 && valid; ++j)
            for (std::int32_t i = u.i0; i < u.i1; ++i) {
              const std::uint64_t key = rasterCellKey(i, j);
              const int c = r.at(i, j);
              if (c >= 0) {
                ++of_class[c];
                if (component.at(key) != own_component) {
                  valid = false;
                  break;
                }
              }
              const auto o = owner.find(key);
              if (o != owner.end()) {
                const RasterRectangle& t = rects[o->second];
                if (t.i0 < u.i0 || t.i1 > u.i1 || t.j0 < u.j0 || t.j1 > u.j1) {
                  valid = false;
                  break;
                }
              }
            }
          const auto area = static_cast<double>(u.i1 - u.i0) * (u.j1 - u.j0);
          if (valid) {
            EXPECT_LT(static_cast<double>(std::max(of_class[0], of_class[1])),
                      d * area - 1e-9)
              << "trial " << trial << " D " << d << ": rectangles " << a << " and " << b
              << " could be one";
          }
        }
    }
  }
  EXPECT_GT(pairs, 1000u);
}

// Shapes whose covers are known by hand: a full block is one rectangle under every
// rule; a staircase of rows of 3, 2 and 1 cells is 3 rectangles under the paper's rule
// (no equal runs) and at the minimum (2 reflex corners, no chord: 2 - 0 + 1); an L of
// a row of 3 cells and a column of 2 above its first cell is 2 under the paper's rule.
TEST(RectangleMerge, KnownShapes)
{
  Raster block;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 4; ++i) {
      block.keys.push_back(rasterCellKey(i, j));
      block.classes.push_back(0);
    }
  for (const auto rule : {RectangleMergeRule::PAPER, RectangleMergeRule::MIN_RECTANGLES,
                          RectangleMergeRule::DENSITY}) {
    const auto rects =
      planar_grid::mergeRasterRectangles(block.keys, block.classes, rule);
    ASSERT_EQ(rects.size(), 1u);
    EXPECT_EQ(rects[0].i0, 0);
    EXPECT_EQ(rects[0].i1, 4);
    EXPECT_EQ(rects[0].j0, 0);
    EXPECT_EQ(rects[0].j1, 3);
  }
  Raster stairs;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3 - j; ++i) {
      stairs.keys.push_back(rasterCellKey(i, j));
      stairs.classes.push_back(0);
    }
  EXPECT_EQ(planar_grid::mergeRasterRectangles(stairs.keys, stairs.classes,
                                               RectangleMergeRule::PAPER)
              .size(),
            3u);
  EXPECT_EQ(planar_grid::mergeRasterRectangles(stairs.keys, stairs.classes,
                                               RectangleMergeRule::MIN_RECTANGLES)
              .size(),
            3u);
  Raster l_shape;
  for (const auto& c :
       {std::make_pair(0, 0), std::make_pair(1, 0), std::make_pair(2, 0),
        std::make_pair(0, 1), std::make_pair(0, 2)}) {
    l_shape.keys.push_back(rasterCellKey(c.first, c.second));
    l_shape.classes.push_back(0);
  }
  std::sort(l_shape.keys.begin(), l_shape.keys.end());
  // [0, 3) in row 0, then [0, 1) in rows 1 and 2, stacked
  EXPECT_EQ(planar_grid::mergeRasterRectangles(l_shape.keys, l_shape.classes,
                                               RectangleMergeRule::PAPER)
              .size(),
            2u);
}

TEST(RectangleMerge, InvalidInputThrowsAndEmptyGivesNothing)
{
  EXPECT_TRUE(
    planar_grid::mergeRasterRectangles({}, {}, RectangleMergeRule::MIN_RECTANGLES)
      .empty());
  EXPECT_THROW(planar_grid::mergeRasterRectangles({rasterCellKey(0, 0)}, {},
                                                  RectangleMergeRule::PAPER),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::mergeRasterRectangles({rasterCellKey(0, 0)}, {0},
                                                  RectangleMergeRule::DENSITY, 0.4),
               planar_grid::Exception);
  EXPECT_EQ(planar_grid::rectangleMergeRuleFromString("density"),
            RectangleMergeRule::DENSITY);
  EXPECT_EQ(planar_grid::toString(RectangleMergeRule::MIN_RECTANGLES),
            "min_rectangles");
  EXPECT_THROW(planar_grid::rectangleMergeRuleFromString("largest"),
               planar_grid::Exception);
}

// rasterCellKey() orders by row, then column, over negative and positive indices.
TEST(RectangleMerge, CellKeysOrderByRowThenColumn)
{
  const std::int32_t values[] = {-2000000000, -7, -1, 0, 1, 8, 2000000000};
  for (const auto j : values)
    for (const auto i : values) {
      const std::uint64_t key = rasterCellKey(i, j);
      EXPECT_EQ(rasterCellI(key), i);
      EXPECT_EQ(rasterCellJ(key), j);
      for (const auto j2 : values)
        for (const auto i2 : values)
          EXPECT_EQ(key < rasterCellKey(i2, j2), j < j2 || (j == j2 && i < i2));
    }
}
