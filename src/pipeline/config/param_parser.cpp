// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/pipeline/param_parser.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <string>
#include <vector>

namespace planar_grid {

ParamValues
parseParams(const YAML::Node& node,
            const std::vector<ParamSpec>& specs,
            const std::string& file,
            const std::string& stage_type)
{
  ParamValues values = defaultParams(specs);
  if (!node || node.IsNull())
    return values;
  const YamlReader reader(file, "");
  reader.forEachKey(
    node, "params of stage '" + stage_type + "'",
    [&](const std::string& key, const YAML::Node& key_node, const YAML::Node& value) {
      const auto spec =
        std::find_if(specs.begin(), specs.end(),
                     [&key](const ParamSpec& s) { return s.key == key; });
      if (spec == specs.end()) {
        std::string known;
        for (const auto& s : specs)
          known += (known.empty() ? "" : ", ") + s.key;
        reader.fail(key_node,
                    "unknown parameter '" + key + "' of stage '" + stage_type
                      + "'; known: " + (known.empty() ? std::string("(none)") : known));
      }
      const std::string where = "parameter '" + key + "' of stage '" + stage_type + "'";
      if (!value.IsScalar())
        reader.fail(value, where + " must be " + formatParamType(*spec, "|"));
      try {
        switch (spec->type) {
          case ParamSpec::Type::DOUBLE: {
            const double v = value.as<double>();
            if (!spec->range.contains(v))
              reader.fail(value, where + " = " + value.Scalar() + " is out of range "
                                   + formatParamRange(spec->range, spec->unit));
            values.set(key, v);
            break;
          }
          case ParamSpec::Type::INT: {
            const int v = value.as<int>();
            if (!spec->range.contains(v))
              reader.fail(value, where + " = " + value.Scalar() + " is out of range "
                                   + formatParamRange(spec->range, spec->unit));
            values.set(key, v);
            break;
          }
          case ParamSpec::Type::BOOL:
            values.set(key, value.as<bool>());
            break;
          case ParamSpec::Type::CHOICE: {
            const std::string v = value.as<std::string>();
            if (std::find(spec->choices.begin(), spec->choices.end(), v)
                == spec->choices.end())
              reader.fail(value, where + " = '" + v + "' must be "
                                   + formatParamType(*spec, "|"));
            values.set(key, v);
            break;
          }
        }
      } catch (const YAML::BadConversion&) {
        reader.fail(value, where + " = '" + value.Scalar() + "' must be "
                             + formatParamType(*spec, "|"));
      }
    });
  return values;
}

} // namespace planar_grid
