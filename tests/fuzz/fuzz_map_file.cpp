// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: planar_grid::PlanarGridMap::load() on arbitrary bytes written to a
// temporary file. The contract (planar_grid_map.h): a map or a planar_grid::Exception
// (IOError) naming the file; anything else (a crash, a sanitizer report, another
// exception type, a huge allocation) is a finding.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <cstddef>
#include <cstdint>

#include "fuzz_input_file.h"

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  static const planar_grid::fuzz::FuzzInputFile file("map.pgmap");
  try {
    const planar_grid::PlanarGridMap map =
      planar_grid::PlanarGridMap::load(file.write(data, size));
    (void)map.getMemory();
  } catch (const planar_grid::Exception&) {
  }
  return 0;
}
