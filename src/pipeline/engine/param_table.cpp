// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/param_table.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>

namespace planar_grid {

std::string
formatParamChoices(const ParamSpec& spec, const std::string& separator)
{
  std::string list;
  for (const auto& c : spec.choices)
    list += (list.empty() ? "" : separator) + c;
  return list;
}

std::string
formatParamRange(const ParamSpec& spec)
{
  if (spec.type == ParamSpec::Type::DOUBLE || spec.type == ParamSpec::Type::INT)
    return formatParamRange(spec.range);
  return "";
}

std::string
formatParamType(const ParamSpec& spec, const std::string& choice_separator)
{
  switch (spec.type) {
    case ParamSpec::Type::DOUBLE:
      return "number";
    case ParamSpec::Type::INT:
      return "integer";
    case ParamSpec::Type::BOOL:
      return "true or false";
    case ParamSpec::Type::CHOICE:
      break;
  }
  return "one of " + formatParamChoices(spec, choice_separator);
}

void
insertParamSpec(std::vector<ParamSpec>& specs,
                const std::string& after,
                const ParamSpec& spec)
{
  const auto it = std::find_if(specs.begin(), specs.end(),
                               [&](const ParamSpec& s) { return s.key == after; });
  if (it == specs.end())
    throw Exception("insertParamSpec: no key '" + after + "' to put '" + spec.key
                    + "' after");
  specs.insert(it + 1, spec);
}

ParamSpec
ParamSpec::real(const std::string& key,
                double default_value,
                double min,
                double max,
                const std::string& unit,
                const std::string& description)
{
  return real(key, default_value, ParamRange::closed(min, max), unit, description);
}

ParamSpec
ParamSpec::real(const std::string& key,
                double default_value,
                const ParamRange& range,
                const std::string& unit,
                const std::string& description)
{
  ParamSpec s;
  s.key = key;
  s.type = Type::DOUBLE;
  s.default_value = formatParamNumber(default_value);
  s.range = range;
  s.unit = unit;
  s.description = description;
  return s;
}

ParamSpec
ParamSpec::integer(const std::string& key,
                   int default_value,
                   int min,
                   int max,
                   const std::string& unit,
                   const std::string& description)
{
  return integer(key, default_value, ParamRange::closed(min, max), unit, description);
}

ParamSpec
ParamSpec::integer(const std::string& key,
                   int default_value,
                   const ParamRange& range,
                   const std::string& unit,
                   const std::string& description)
{
  ParamSpec s = real(key, default_value, range, unit, description);
  s.type = Type::INT;
  return s;
}

ParamSpec
ParamSpec::flag(const std::string& key,
                bool default_value,
                const std::string& description)
{
  ParamSpec s;
  s.key = key;
  s.type = Type::BOOL;
  s.default_value = default_value ? "true" : "false";
  s.description = description;
  return s;
}

ParamSpec
ParamSpec::choice(const std::string& key,
                  const std::string& default_value,
                  const std::vector<std::string>& choices,
                  const std::string& description)
{
  ParamSpec s;
  s.key = key;
  s.type = Type::CHOICE;
  s.default_value = default_value;
  s.choices = choices;
  s.description = description;
  return s;
}

double
ParamValues::getDouble(const std::string& key) const
{
  const auto it = values_.find(key);
  if (it == values_.end() || !std::holds_alternative<double>(it->second))
    throw Exception("ParamValues: no number parameter '" + key + "'");
  return std::get<double>(it->second);
}

int
ParamValues::getInt(const std::string& key) const
{
  const auto it = values_.find(key);
  if (it == values_.end() || !std::holds_alternative<int>(it->second))
    throw Exception("ParamValues: no integer parameter '" + key + "'");
  return std::get<int>(it->second);
}

bool
ParamValues::getBool(const std::string& key) const
{
  const auto it = values_.find(key);
  if (it == values_.end() || !std::holds_alternative<bool>(it->second))
    throw Exception("ParamValues: no true/false parameter '" + key + "'");
  return std::get<bool>(it->second);
}

const std::string&
ParamValues::getChoice(const std::string& key) const
{
  const auto it = values_.find(key);
  if (it == values_.end() || !std::holds_alternative<std::string>(it->second))
    throw Exception("ParamValues: no choice parameter '" + key + "'");
  return std::get<std::string>(it->second);
}

void
ParamValues::set(const std::string& key,
                 std::variant<double, int, bool, std::string> value)
{
  values_[key] = std::move(value);
}

std::string
ParamValues::toString(const std::string& key) const
{
  const auto it = values_.find(key);
  if (it == values_.end())
    return "";
  return std::visit(
    [](const auto& v) -> std::string {
      using V = std::decay_t<decltype(v)>;
      if constexpr (std::is_same_v<V, std::string>)
        return v;
      else if constexpr (std::is_same_v<V, bool>)
        return v ? "true" : "false";
      else
        return formatParamNumber(static_cast<double>(v));
    },
    it->second);
}

ParamValues
defaultParams(const std::vector<ParamSpec>& specs)
{
  ParamValues values;
  for (const auto& spec : specs) {
    switch (spec.type) {
      case ParamSpec::Type::DOUBLE:
        values.set(spec.key, std::stod(spec.default_value));
        break;
      case ParamSpec::Type::INT:
        values.set(spec.key, std::stoi(spec.default_value));
        break;
      case ParamSpec::Type::BOOL:
        values.set(spec.key, spec.default_value == "true");
        break;
      case ParamSpec::Type::CHOICE:
        values.set(spec.key, spec.default_value);
        break;
    }
  }
  return values;
}

std::string
describeParams(const std::vector<ParamSpec>& specs)
{
  std::ostringstream out;
  if (specs.empty())
    out << "    (no parameters)\n";
  for (const auto& spec : specs) {
    out << "    " << std::left << std::setw(28) << spec.key << " " << std::setw(12)
        << formatParamType(spec, "|");
    out << " default " << spec.default_value;
    const std::string range = formatParamRange(spec);
    if (!range.empty())
      out << ", range " << range;
    if (!spec.unit.empty())
      out << " " << spec.unit;
    out << "\n        " << spec.description << "\n";
  }
  return out.str();
}

} // namespace planar_grid
