// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::merge() on a synthetic street whose surfaces are known exactly: maps
// of parts of one drive, merged, against the map of the whole drive.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "street_scene.h"

namespace {

// The synthetic street (street_scene.h): its surfaces, frames, views and probes.
namespace street = planar_grid_test::street;
using planar_grid::ExplicitSpaceGrid;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlanarGridMap;
using planar_grid::PlaneModels;
using planar_grid::SpaceState;
using planar_grid_test::wallCuboid;

/** Share of the probes observed by either map (a state other than UNKNOWN) where the
 * two maps agree; \a observed receives their number. With \a interior, only the
 * probes away from the boundaries of \a a's states count: those whose six neighbours
 * 0.2 m away (two voxels) have the probe's state in \a a. */
double
agreement(const PlanarGridMap& a,
          const PlanarGridMap& b,
          std::size_t& observed,
          bool interior = false)
{
  std::size_t same = 0;
  observed = 0;
  for (const Eigen::Vector3f& p : street::probes()) {
    const SpaceState sa = a.getState(p), sb = b.getState(p);
    if (sa == SpaceState::UNKNOWN && sb == SpaceState::UNKNOWN)
      continue;
    bool inside = true;
    for (int k = 0; k < 6 && interior && inside; ++k) {
      Eigen::Vector3f step = Eigen::Vector3f::Zero();
      step[k / 2] = k % 2 == 0 ? -0.2f : 0.2f;
      inside = a.getState(p + step) == sa;
    }
    if (!inside)
      continue;
    ++observed;
    same += sa == sb ? 1 : 0;
  }
  return observed > 0 ? static_cast<double>(same) / static_cast<double>(observed) : 0.0;
}

/** The cuboids' geometry and probability, sorted, for comparisons up to order. */
std::vector<std::vector<float>>
cuboidSet(const PlanarGridMap& map)
{
  std::vector<std::vector<float>> out;
  for (const PlanarCuboid& c : map.getSurfaceLayer().getCuboids())
    out.push_back({c.is_planar ? 1.0f : 0.0f, c.centre.x(), c.centre.y(), c.centre.z(),
                   c.normal.x(), c.normal.y(), c.normal.z(), c.horizontal_axis.x(),
                   c.horizontal_axis.y(), c.horizontal_axis.z(), c.width_m, c.height_m,
                   c.thickness_m, c.probability});
  std::sort(out.begin(), out.end());
  return out;
}

// ---- the tests ---------------------------------------------------------------------

TEST(PlanarGridMapMerge, TheSceneMakesOnePlanePerSurface)
{
  // The truth the other tests rely on: the whole drive maps the ground, two walls and
  // the end wall as four planes, and the box as non-planar cells.
  const PlanarGridMap full = street::mapFrames(0, street::FRAMES);
  EXPECT_EQ(full.getSurfaceLayer().getPlanes().size(), 4u);
  EXPECT_EQ(full.getSurfaceLayer().getPlaneCount(), 4u);
  std::size_t non_planar = 0;
  for (const PlanarCuboid& c : full.getSurfaceLayer().getCuboids())
    non_planar += c.is_planar ? 0 : 1;
  EXPECT_EQ(non_planar, 8u);
  EXPECT_EQ(full.getState(Eigen::Vector3f(8.0f, 1.0f, 0.2f)), SpaceState::OCCUPIED);
  EXPECT_EQ(full.getState(Eigen::Vector3f(10.0f, 0.0f, 1.5f)), SpaceState::FREE);
  EXPECT_EQ(full.getState(Eigen::Vector3f(10.0f, 3.05f, 1.5f)), SpaceState::OCCUPIED);
}

TEST(PlanarGridMapMerge, AnEmptyMapChangesNothing)
{
  PlanarGridMap map = street::mapFrames(0, street::FRAMES / 2);
  const std::string before = street::bytesOf(map);
  map.merge(PlanarGridMap(street::params()), Eigen::Isometry3d::Identity());
  EXPECT_EQ(street::bytesOf(map), before);

  // and the other way round: an empty map takes the map's planes, cells and voxels
  PlanarGridMap empty(street::params());
  const PlanarGridMap reference = street::copyOf(map);
  empty.merge(map, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(empty.getSpaceLayer() == reference.getSpaceLayer());
  EXPECT_EQ(empty.getSurfaceLayer().getPlanes().size(),
            reference.getSurfaceLayer().getPlanes().size());
  EXPECT_EQ(cuboidSet(empty), cuboidSet(reference));
  EXPECT_EQ(street::bytesOf(map), before); // the merged-in map is unchanged
}

TEST(PlanarGridMapMerge, ACopyDoublesTheEvidenceNotTheCells)
{
  // A map merged with a copy of itself (one recording mapped twice): every plane
  // joins its copy and every cell its copy, so the planes, cells and voxels are those
  // of the map; the evidence doubles, and its means (the probabilities) stay.
  PlanarGridMap map = street::mapFrames(0, street::FRAMES / 2);
  const PlanarGridMap copy = street::copyOf(map);
  map.merge(copy, Eigen::Isometry3d::Identity());
  EXPECT_EQ(map.getSurfaceLayer().getPlanes().size(),
            copy.getSurfaceLayer().getPlanes().size());
  EXPECT_EQ(map.getSurfaceLayer().getCellCount(),
            copy.getSurfaceLayer().getCellCount());
  EXPECT_EQ(cuboidSet(map), cuboidSet(copy));
  EXPECT_TRUE(map.getSpaceLayer() == copy.getSpaceLayer());
}

TEST(PlanarGridMapMerge, MergingAIntoBEqualsMergingBIntoA)
{
  const PlanarGridMap a = street::mapFrames(0, street::FRAMES / 2);
  const PlanarGridMap b = street::mapFrames(street::FRAMES / 2, street::FRAMES);
  PlanarGridMap ab = street::copyOf(a);
  ab.merge(b, Eigen::Isometry3d::Identity());
  PlanarGridMap ba = street::copyOf(b);
  ba.merge(a, Eigen::Isometry3d::Identity());
  EXPECT_EQ(ab.getSurfaceLayer().getPlanes().size(),
            ba.getSurfaceLayer().getPlanes().size());
  EXPECT_TRUE(ab.getSpaceLayer() == ba.getSpaceLayer());
  EXPECT_EQ(cuboidSet(ab), cuboidSet(ba));
  std::size_t observed = 0;
  EXPECT_EQ(agreement(ab, ba, observed), 1.0);
  EXPECT_GT(observed, 10000u);
}

TEST(PlanarGridMapMerge, TwoHalvesOfADriveGiveTheMapOfTheWholeDrive)
{
  const PlanarGridMap full = street::mapFrames(0, street::FRAMES);
  PlanarGridMap merged = street::mapFrames(0, street::FRAMES / 2);
  const PlanarGridMap second = street::mapFrames(street::FRAMES / 2, street::FRAMES);
  // each half saw the ground and both walls: three planes each, and only the second
  // half saw the end wall
  ASSERT_EQ(merged.getSurfaceLayer().getPlanes().size(), 3u);
  ASSERT_EQ(second.getSurfaceLayer().getPlanes().size(), 4u);
  merged.merge(second, Eigen::Isometry3d::Identity());
  // one plane per surface: the halves' planes of one wall became one plane
  EXPECT_EQ(merged.getSurfaceLayer().getPlanes().size(),
            full.getSurfaceLayer().getPlanes().size());
  for (const Eigen::Vector4f& plane : merged.getSurfaceLayer().getPlanes()) {
    bool found = false;
    for (const Eigen::Vector4f& truth : full.getSurfaceLayer().getPlanes())
      found = found
              || (plane.head<3>().dot(truth.head<3>()) > 0.9999f
                  && std::abs(plane[3] - truth[3]) < 0.005f);
    EXPECT_TRUE(found) << plane.transpose();
  }
  // the second half's views are newer: its observations win where both halves saw a
  // voxel, as integration keeps the newest view, which gives the whole drive's voxels
  EXPECT_TRUE(merged.getSpaceLayer() == full.getSpaceLayer());
  EXPECT_EQ(merged.getSpaceLayer().getVoxelCount(SpaceState::OCCUPIED),
            full.getSpaceLayer().getVoxelCount(SpaceState::OCCUPIED));
  EXPECT_EQ(merged.getObservationSpan().first, 0.0);
  EXPECT_EQ(merged.getObservationSpan().last, street::FRAMES - 1.0);
  std::size_t observed = 0;
  const double share = agreement(full, merged, observed);
  RecordProperty("agreement_percent", std::to_string(100.0 * share));
  EXPECT_GE(share, 0.99);
  EXPECT_GT(observed, 10000u);
  // the cells are those of the whole drive: the planar cuboids cover the same area
  double full_area = 0.0, merged_area = 0.0;
  for (const PlanarCuboid& c : full.getSurfaceLayer().getCuboids())
    full_area += c.is_planar ? static_cast<double>(c.width_m) * c.height_m : 0.0;
  for (const PlanarCuboid& c : merged.getSurfaceLayer().getCuboids())
    merged_area += c.is_planar ? static_cast<double>(c.width_m) * c.height_m : 0.0;
  EXPECT_NEAR(merged_area, full_area, 0.02 * full_area);
}

TEST(PlanarGridMapMerge, FourSegmentsMergedInATreeGiveTheDrivesVoxels)
{
  // The drive in four segments merged as planar_grid.distributed merges them:
  // neighbours first, in either argument order, then the two halves.
  const PlanarGridMap full = street::mapFrames(0, street::FRAMES);
  std::vector<PlanarGridMap> segments;
  for (int s = 0; s < 4; ++s)
    segments.push_back(
      street::mapFrames(s * street::FRAMES / 4, (s + 1) * street::FRAMES / 4));
  PlanarGridMap left = street::copyOf(segments[1]);
  left.merge(segments[0], Eigen::Isometry3d::Identity());
  PlanarGridMap right = street::copyOf(segments[2]);
  right.merge(segments[3], Eigen::Isometry3d::Identity());
  right.merge(left, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(right.getSpaceLayer() == full.getSpaceLayer());

  // The same segments without their order (maps from files without a span): occupied
  // wins where they disagree, which adds occupied voxels the drive's map does not hold
  // and removes none.
  PlanarGridMap unordered(street::params());
  for (PlanarGridMap& segment : segments) {
    segment.setObservationSpan(PlanarGridMap::ObservationSpan());
    unordered.merge(segment, Eigen::Isometry3d::Identity());
  }
  EXPECT_TRUE(unordered.getObservationSpan().empty());
  std::size_t added = 0, lost = 0;
  full.getSpaceLayer().forEachVoxel(
    [&](const ExplicitSpaceGrid::VoxelKey& key, SpaceState state) {
      lost += state == SpaceState::OCCUPIED
              && unordered.getSpaceLayer().getState(key) != SpaceState::OCCUPIED;
    });
  unordered.getSpaceLayer().forEachVoxel(
    [&](const ExplicitSpaceGrid::VoxelKey& key, SpaceState state) {
      added += state == SpaceState::OCCUPIED
               && full.getSpaceLayer().getState(key) != SpaceState::OCCUPIED;
    });
  RecordProperty("unordered_extra_occupied", std::to_string(added));
  EXPECT_GT(added, 0u);
  EXPECT_EQ(lost, 0u);
}

TEST(PlanarGridMapMerge, TheObservationSpanIsSavedAndUnionedAndOptional)
{
  PlanarGridMap a = street::mapFrames(2, 5);
  EXPECT_EQ(a.getObservationSpan().first, 2.0);
  EXPECT_EQ(a.getObservationSpan().last, 4.0);
  const PlanarGridMap loaded = street::copyOf(a);
  EXPECT_EQ(loaded.getObservationSpan().first, 2.0);
  EXPECT_EQ(loaded.getObservationSpan().last, 4.0);
  EXPECT_NE(street::bytesOf(a).find("\nobservation_span 2 4\n"), std::string::npos);
  // merging the empty map (no span) leaves the span; the union otherwise
  a.merge(PlanarGridMap(street::params()), Eigen::Isometry3d::Identity());
  EXPECT_EQ(a.getObservationSpan().first, 2.0);
  EXPECT_EQ(a.getObservationSpan().last, 4.0);
  a.merge(street::mapFrames(7, 8), Eigen::Isometry3d::Identity());
  EXPECT_EQ(a.getObservationSpan().first, 2.0);
  EXPECT_EQ(a.getObservationSpan().last, 7.0);
  // a map without a span writes no line (the file of the versions before it) and
  // reads back without one
  PlanarGridMap none = street::mapFrames(0, 1);
  none.setObservationSpan(PlanarGridMap::ObservationSpan());
  EXPECT_EQ(street::bytesOf(none).find("observation_span"), std::string::npos);
  EXPECT_TRUE(street::copyOf(none).getObservationSpan().empty());
  EXPECT_THROW(none.noteObservationOrder(std::numeric_limits<double>::quiet_NaN()),
               planar_grid::Exception);
  // a bad span line is refused by name
  std::string bytes = street::bytesOf(a);
  const std::string line = "observation_span 2 7\n";
  const std::size_t at = bytes.find(line);
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, line.size(), "observation_span 7 2\n");
  try {
    PlanarGridMap::deserialize(bytes, "swapped");
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(std::string(e.what()).find("observation_span"), std::string::npos)
      << e.what();
  }
}

TEST(PlanarGridMapMerge, TheTransformMovesTheOtherMapIntoThisFrame)
{
  // The second half mapped in a frame turned 0.3 rad about a near-vertical axis and
  // shifted: merged with this_T_other, it gives the map of the halves mapped in one
  // frame, up to the resampling of the voxels and raster cells (each to the nearest
  // cell): away from the boundaries between states the maps agree, and at them
  // (the edges of the views, the surfaces) cells one voxel off differ.
  Eigen::Isometry3d other_T_world = Eigen::Isometry3d::Identity();
  other_T_world.linear() =
    Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.1, -0.05, 1.0).normalized())
      .toRotationMatrix();
  other_T_world.translation() = Eigen::Vector3d(1.234, -0.567, 0.089);
  PlanarGridMap reference = street::mapFrames(0, street::FRAMES / 2);
  reference.merge(street::mapFrames(street::FRAMES / 2, street::FRAMES),
                  Eigen::Isometry3d::Identity());
  PlanarGridMap merged = street::mapFrames(0, street::FRAMES / 2);
  merged.merge(street::mapFrames(street::FRAMES / 2, street::FRAMES, other_T_world),
               other_T_world.inverse());
  EXPECT_EQ(merged.getSurfaceLayer().getPlanes().size(),
            reference.getSurfaceLayer().getPlanes().size());
  for (const Eigen::Vector4f& plane : merged.getSurfaceLayer().getPlanes()) {
    bool found = false;
    for (const Eigen::Vector4f& truth : reference.getSurfaceLayer().getPlanes())
      found = found
              || (plane.head<3>().dot(truth.head<3>()) > 0.99999f
                  && std::abs(plane[3] - truth[3]) < 0.001f);
    EXPECT_TRUE(found) << plane.transpose();
  }
  std::size_t observed = 0;
  EXPECT_GE(agreement(reference, merged, observed, true), 0.999);
  EXPECT_GT(observed, 50000u);
  EXPECT_GE(agreement(reference, merged, observed), 0.95);
  // without the transform the second half lands elsewhere
  PlanarGridMap wrong = street::mapFrames(0, street::FRAMES / 2);
  wrong.merge(street::mapFrames(street::FRAMES / 2, street::FRAMES, other_T_world),
              Eigen::Isometry3d::Identity());
  EXPECT_LT(agreement(reference, wrong, observed, true), 0.95);
}

TEST(PlanarGridMapMerge, AWholeVoxelTranslationMovesTheVoxelsExactly)
{
  // The second half's space layer moved by whole voxels (8 on x: whole 8^3 blocks; -3
  // on y and 5 on z: not) and merged back with the inverse translation gives exactly
  // the layer merged without moving.
  const PlanarGridMap first = street::mapFrames(0, street::FRAMES / 2);
  const PlanarGridMap second = street::mapFrames(street::FRAMES / 2, street::FRAMES);
  for (const Eigen::Vector3i& offset :
       {Eigen::Vector3i(8, 0, 0), Eigen::Vector3i(8, -3, 5)}) {
    SCOPED_TRACE(offset.transpose());
    PlanarGridMap shifted(street::params());
    shifted.setObservationSpan(second.getObservationSpan());
    second.getSpaceLayer().forEachVoxel(
      [&](const ExplicitSpaceGrid::VoxelKey& key, SpaceState state) {
        shifted.getSpaceLayer().setState(key + offset, state);
      });
    Eigen::Isometry3d this_T_other = Eigen::Isometry3d::Identity();
    this_T_other.translation() = -0.1 * offset.cast<double>();
    PlanarGridMap reference = street::copyOf(first), merged = street::copyOf(first);
    reference.merge(second, Eigen::Isometry3d::Identity());
    merged.merge(shifted, this_T_other);
    EXPECT_TRUE(merged.getSpaceLayer() == reference.getSpaceLayer());
  }
}

TEST(PlanarGridMapMerge, TheSpaceLayersCombineByRank)
{
  // Maps without observation spans (no newer map), every pair of states, both priors:
  // occupied > free > unknown (occluded) > never observed, against a brute-force table.
  for (const SpaceState prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    SCOPED_TRACE(planar_grid::toString(prior));
    PlanarGridMap::Params p = street::params();
    p.space.prior = prior;
    PlanarGridMap a(p), b(p);
    // state index 3: never observed (not set)
    const auto rank = [](int s) {
      return s == 1 ? 3 : s == 0 ? 2 : s == 2 ? 1 : 0;
    };
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> state(0, 3);
    std::map<std::tuple<int, int, int>, int> expected;
    for (int x = -20; x < 20; ++x)
      for (int y = -3; y < 3; ++y)
        for (int z = 0; z < 4; ++z) {
          const int sa = state(rng), sb = state(rng);
          if (sa < 3)
            a.getSpaceLayer().setState({x, y, z}, static_cast<SpaceState>(sa));
          if (sb < 3)
            b.getSpaceLayer().setState({x, y, z}, static_cast<SpaceState>(sb));
          expected[{x, y, z}] = rank(sa) >= rank(sb) ? sa : sb;
        }
    a.merge(b, Eigen::Isometry3d::Identity());
    std::size_t wrong = 0;
    for (const auto& [key, s] : expected) {
      const auto [x, y, z] = key;
      const SpaceState want = s == 3 ? prior : static_cast<SpaceState>(s);
      wrong += a.getSpaceLayer().getState(ExplicitSpaceGrid::VoxelKey(x, y, z)) != want;
    }
    EXPECT_EQ(wrong, 0u);
    // only observed voxels are stored: free and occupied, and with the free prior the
    // occluded ones (with the unknown prior occluded and never observed are one state)
    std::size_t observed = 0;
    for (const auto& kv : expected)
      observed += kv.second < (prior == SpaceState::FREE ? 3 : 2) ? 1 : 0;
    std::size_t stored = 0;
    a.getSpaceLayer().forEachVoxel(
      [&stored](const ExplicitSpaceGrid::VoxelKey&, SpaceState) { ++stored; });
    EXPECT_EQ(stored, observed);
  }
}

TEST(PlanarGridMapMerge, TheNewerMapsObservationsWin)
{
  // Every pair of states, both priors, maps whose spans are ordered: where both
  // observed a voxel free or occupied the newer map's state wins; an observed state
  // beats occluded, occluded beats never observed; against a brute-force table, in
  // both argument orders. Spans that overlap fall back to the rank.
  for (const SpaceState prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    SCOPED_TRACE(planar_grid::toString(prior));
    PlanarGridMap::Params p = street::params();
    p.space.prior = prior;
    PlanarGridMap older(p), newer(p);
    older.noteObservationOrder(10.0);
    older.noteObservationOrder(19.0);
    newer.noteObservationOrder(20.0);
    // state index 3: never observed (not set)
    const auto rank = [](int s) {
      return s == 1 ? 3 : s == 0 ? 2 : s == 2 ? 1 : 0;
    };
    std::mt19937 rng(12);
    std::uniform_int_distribution<int> state(0, 3);
    std::map<std::tuple<int, int, int>, int> ordered, by_rank;
    for (int x = -20; x < 20; ++x)
      for (int y = -3; y < 3; ++y)
        for (int z = 0; z < 4; ++z) {
          const int so = state(rng), sn = state(rng);
          if (so < 3)
            older.getSpaceLayer().setState({x, y, z}, static_cast<SpaceState>(so));
          if (sn < 3)
            newer.getSpaceLayer().setState({x, y, z}, static_cast<SpaceState>(sn));
          ordered[{x, y, z}] = sn <= 1 ? sn : (rank(so) >= rank(sn) ? so : sn);
          by_rank[{x, y, z}] = rank(so) >= rank(sn) ? so : sn;
        }
    const auto wrong = [prior](const PlanarGridMap& m,
                               const std::map<std::tuple<int, int, int>, int>& table) {
      std::size_t n = 0;
      for (const auto& [key, s] : table) {
        const auto [x, y, z] = key;
        const SpaceState want = s == 3 ? prior : static_cast<SpaceState>(s);
        n += m.getSpaceLayer().getState(ExplicitSpaceGrid::VoxelKey(x, y, z)) != want;
      }
      return n;
    };
    PlanarGridMap on = street::copyOf(older), no = street::copyOf(newer);
    on.merge(newer, Eigen::Isometry3d::Identity());
    no.merge(older, Eigen::Isometry3d::Identity());
    EXPECT_EQ(wrong(on, ordered), 0u);
    EXPECT_EQ(wrong(no, ordered), 0u);
    EXPECT_TRUE(on.getSpaceLayer() == no.getSpaceLayer());
    EXPECT_EQ(on.getObservationSpan().first, 10.0);
    EXPECT_EQ(on.getObservationSpan().last, 20.0);
    // resampled by a transform that is not a whole-voxel translation, the same rule
    Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
    turn.linear() =
      Eigen::AngleAxisd(1e-9, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    PlanarGridMap resampled = street::copyOf(older);
    resampled.merge(newer, turn);
    EXPECT_EQ(wrong(resampled, ordered), 0u);
    // overlapping spans: no newer map, the rank decides
    PlanarGridMap overlapping = street::copyOf(newer);
    overlapping.noteObservationOrder(15.0);
    PlanarGridMap ranked = street::copyOf(older);
    ranked.merge(overlapping, Eigen::Isometry3d::Identity());
    EXPECT_EQ(wrong(ranked, by_rank), 0u);
  }
}

TEST(PlanarGridMapMerge, AWallSeenByBothMapsBecomesOnePlane)
{
  // The same wall (x = 2, normal -x) seen by two maps with plane estimates 1 cm apart,
  // on two stretches 0.9 m apart (their rasters do not touch, so only the association
  // joins them): one plane whose evidence is both maps' (the fit between them), not
  // two parallel ones; a wall seen by one map only stays its own plane.
  const auto wall = [](float x, float y0, int frames, PlanarGridMap& map) {
    for (int k = 0; k < frames; ++k) {
      const Eigen::Vector3f face(x, y0 + 0.3f * static_cast<float>(k), 1.0f);
      const PlaneModels planes{Eigen::Vector4f(-1.0f, 0.0f, 0.0f, x)};
      PlanarCuboids cuboids{wallCuboid(face, -Eigen::Vector3f::UnitX(),
                                       -Eigen::Vector3f::UnitY(), 2.0f, 2.0f, 0)};
      map.integrateSurface(cuboids, planes, {}, {});
    }
  };
  PlanarGridMap a(street::params()), b(street::params());
  wall(2.0f, 0.0f, 3, a);  // y in [-1, 1.6]
  wall(2.01f, 3.5f, 3, b); // y in [2.5, 5.1]
  wall(-4.0f, 0.0f, 1, b); // another wall (normal -x too, 6 m behind)
  a.merge(b, Eigen::Isometry3d::Identity());
  const PlaneModels& planes = a.getSurfaceLayer().getPlanes();
  ASSERT_EQ(planes.size(), 2u);
  // the least-squares plane of both walls' faces lies between them: the 2.00 m faces
  // on one side, the 2.01 m faces on the other, each within 1 cm
  const auto distance = [&planes](const Eigen::Vector3f& p) {
    return planes[0].head<3>().dot(p) + planes[0][3];
  };
  const float to_a = distance(Eigen::Vector3f(2.0f, 0.3f, 1.0f));
  const float to_b = distance(Eigen::Vector3f(2.01f, 3.8f, 1.0f));
  EXPECT_LT(to_a * to_b, 0.0f);
  EXPECT_LT(std::abs(to_a), 0.01f);
  EXPECT_LT(std::abs(to_b), 0.01f);
  EXPECT_NEAR(planes[1][3], -4.0f, 1e-4f);
  // the plane holds both stretches, and not the gap between them
  const PlanarCuboid* near = a.getSurfaceLayer().findCuboid({2.06f, -0.9f, 1.0f});
  const PlanarCuboid* far = a.getSurfaceLayer().findCuboid({2.06f, 5.0f, 1.0f});
  ASSERT_NE(near, nullptr);
  ASSERT_NE(far, nullptr);
  EXPECT_EQ(near->plane_id, 0);
  EXPECT_EQ(far->plane_id, 0);
  EXPECT_EQ(a.getSurfaceLayer().findCuboid({2.06f, 2.0f, 1.0f}), nullptr);
}

TEST(PlanarGridMapMerge, MismatchedParametersAreRefusedAndLeaveTheMapUnchanged)
{
  PlanarGridMap map = street::mapFrames(0, 2);
  const std::string before = street::bytesOf(map);
  const auto refused = [&](const PlanarGridMap::Params& p, const std::string& name) {
    PlanarGridMap other(p);
    try {
      map.merge(other, Eigen::Isometry3d::Identity());
      ADD_FAILURE() << name << ": no exception";
    } catch (const planar_grid::Exception& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
    EXPECT_EQ(street::bytesOf(map), before) << name;
  };
  PlanarGridMap::Params p = street::params();
  p.resolution_m = 0.2;
  refused(p, "resolution_m");
  p = street::params();
  p.space.prior = SpaceState::FREE;
  refused(p, "prior");
  p = street::params();
  p.surface.thickness_m = 0.2;
  refused(p, "thickness_m");
  p = street::params();
  p.surface.plane_merge_angle_rad = 0.2;
  refused(p, "plane_merge_angle_rad");
  p = street::params();
  p.surface.merge_rule = planar_grid::SurfaceMergeRule::PAPER;
  refused(p, "merge_rule");
  p = street::params();
  p.surface.close_gaps_cells = 3;
  refused(p, "close_gaps_cells");
  // the parameters of later integration are this map's: no refusal
  p = street::params();
  p.space.max_range_m = 30.0;
  p.clear_planar = true;
  EXPECT_NO_THROW(map.merge(PlanarGridMap(p), Eigen::Isometry3d::Identity()));
  // a map into itself, a transform that is not rigid
  EXPECT_THROW(map.merge(map, Eigen::Isometry3d::Identity()), planar_grid::Exception);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;
  EXPECT_THROW(map.merge(PlanarGridMap(street::params()), scaled),
               planar_grid::Exception);
  Eigen::Isometry3d nan = Eigen::Isometry3d::Identity();
  nan.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(map.merge(PlanarGridMap(street::params()), nan), planar_grid::Exception);
  EXPECT_EQ(street::bytesOf(map), before);
}

} // namespace
