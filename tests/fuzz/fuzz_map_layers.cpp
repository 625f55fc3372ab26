// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the two binary sections of a map file decoded directly, without
// the file header's CRC-32 that makes most mutations of a whole file fail early.
// The first byte picks the decoder: even = ExplicitSpaceGrid::deserialize, odd =
// SurfaceLayer::deserialize; the rest is the section. The contract: the layer decodes
// or a planar_grid::Exception (IOError) is thrown; anything else is a finding. A
// decoded layer is encoded again and must decode to an equal layer.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/map/surface_layer.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

namespace {

template <typename Layer, typename Params>
void
decodeAndReencode(const Params& params, const std::uint8_t* data, std::size_t size)
{
  Layer layer(params);
  try {
    layer.deserialize(data, size);
  } catch (const planar_grid::Exception&) {
    return;
  }
  std::vector<std::uint8_t> bytes;
  layer.serialize(bytes);
  Layer again(params);
  again.deserialize(bytes.data(), bytes.size());
  if (!(again == layer))
    std::abort(); // the round trip of a decoded layer must be exact
}

} // namespace

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  if (size == 0)
    return 0;
  if (data[0] % 2 == 0)
    decodeAndReencode<planar_grid::ExplicitSpaceGrid>(
      planar_grid::ExplicitSpaceGrid::Params{}, data + 1, size - 1);
  else
    decodeAndReencode<planar_grid::SurfaceLayer>(planar_grid::SurfaceLayer::Params{},
                                                 data + 1, size - 1);
  return 0;
}
