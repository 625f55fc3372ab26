// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/param_range.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>

#include <sstream>
#include <string>
#include <vector>

namespace planar_grid {

namespace {

/** Text for a Markdown table cell: '|' escaped, so that a choice list or a formula
 * stays in its cell. */
std::string
cell(const std::string& text)
{
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    if (c == '|')
      out += "\\|";
    else
      out += c;
  }
  return out;
}

std::string
typeCell(const ParamSpec& spec)
{
  if (spec.type == ParamSpec::Type::CHOICE)
    return "one of `" + formatParamChoices(spec, "`, `") + "`";
  return formatParamType(spec, "");
}

std::string
scalingNote(const ParamSpec& spec)
{
  switch (spec.cell_size_scaling) {
    case ParamSpec::CellSizeScaling::NONE:
      return "";
    case ParamSpec::CellSizeScaling::CELL_SIZE:
      return " *Follows the cell size r (top-level `cell_size_m`, planar_grid_eval): "
             "set to r.*";
    case ParamSpec::CellSizeScaling::POINTS_PER_AREA:
      return " *Follows the cell size r (top-level `cell_size_m`, planar_grid_eval): "
             "scaled by (0.1 / r)^2.*";
    case ParamSpec::CellSizeScaling::LENGTH:
      return " *Follows the cell size r (top-level `cell_size_m`, planar_grid_eval): "
             "scaled by r / 0.1.*";
  }
  return "";
}

} // namespace

std::string
stageReferenceMarkdown()
{
  std::ostringstream out;
  out
    << "# Pipeline stages and their parameters\n\n"
       "Every stage type of the pipeline's YAML (`- type: NAME` with `params:` in the "
       "`pipeline:` list), with each parameter's type, default, range and unit. This "
       "page is generated from the stage tables, the same ones the configuration "
       "check, `planar_grid_pipeline --list-stages`, the Python docstrings and "
       "`config/example.yaml` come from:\n\n"
       "```sh\n"
       "build/tools/planar_grid_pipeline --stage-reference > docs/STAGES.md\n"
       "```\n\n"
       "The test `PipelineTool.StageReferenceIsCurrent` fails when this page differs "
       "from the tables. In a range a square bracket includes its end and a round one "
       "excludes it; a value outside its range, an unknown key or a value of the wrong "
       "type is refused with its file:line:col.\n\n"
       "Stages:";
  const auto& registry = stageRegistry();
  for (std::size_t i = 0; i < registry.size(); ++i)
    out << (i == 0 ? " " : ", ") << "[`" << registry[i].type << "`](#"
        << registry[i].type << ")";
  out << ".\n";
  for (const auto& info : registry) {
    out << "\n## " << info.type << "\n\n" << info.description << "\n\n";
    out << "- Role: " << (info.role == StageRole::FRONT_END ? "front end" : "mapping")
        << (info.repeatable ? "; may be listed more than once" : "") << ".\n";
    out << "- Needs: " << stageDataNames(info.needs) << ".\n";
    out << "- Produces: " << stageDataNames(info.produces) << ".\n";
    if (info.params.empty()) {
      out << "\nNo parameters.\n";
      continue;
    }
    out << "\n| key | type | default | range | unit | what it does |\n"
           "|---|---|---|---|---|---|\n";
    for (const auto& spec : info.params)
      out << "| `" << spec.key << "` | " << cell(typeCell(spec)) << " | `"
          << spec.default_value << "` | " << formatParamRange(spec) << " | "
          << cell(spec.unit) << " | " << cell(spec.description + scalingNote(spec))
          << " |\n";
  }
  return out.str();
}

} // namespace planar_grid
