// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: planar_grid::parsePipelineConfig() on arbitrary YAML text. The
// contract (pipeline_config.h): a configuration or a planar_grid::ConfigError /
// IOError; anything else (a crash, a sanitizer report, a YAML::Exception or another
// exception escaping) is a finding.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)planar_grid::parsePipelineConfig(text, "fuzz.yaml", "/nonexistent");
  } catch (const planar_grid::Exception&) {
  }
  return 0;
}
