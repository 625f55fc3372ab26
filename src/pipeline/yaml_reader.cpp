// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

namespace planar_grid {

namespace fs = std::filesystem;

YamlReader::YamlReader(std::string file, std::string base_folder) :
    file_(std::move(file)), base_folder_(std::move(base_folder))
{}

void
YamlReader::fail(const YAML::Node& node, const std::string& message) const
{
  const YAML::Mark mark = node.Mark();
  throw ConfigError(file_, mark.is_null() ? 0 : mark.line + 1,
                    mark.is_null() ? 0 : mark.column + 1, message);
}

void
YamlReader::requireMap(const YAML::Node& node, const std::string& what) const
{
  if (!node.IsMap())
    fail(node, what + " must be a map of key: value");
}

void
YamlReader::forEachKey(
  const YAML::Node& node,
  const std::string& what,
  const std::function<void(const std::string&, const YAML::Node&, const YAML::Node&)>&
    visit) const
{
  requireMap(node, what);
  std::set<std::string> seen;
  for (const auto& item : node) {
    if (!item.first.IsScalar())
      fail(item.first, "a key in " + what + " must be a plain name");
    const std::string key = item.first.as<std::string>();
    if (!seen.insert(key).second)
      fail(item.first, "key '" + key + "' is given twice in " + what);
    visit(key, item.first, item.second);
  }
}

void
YamlReader::checkKeys(const YAML::Node& node,
                      const std::vector<std::string>& allowed,
                      const std::string& what) const
{
  forEachKey(
    node, what,
    [&](const std::string& key, const YAML::Node& key_node, const YAML::Node&) {
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end())
        return;
      std::string list;
      for (const auto& a : allowed)
        list += (list.empty() ? "" : ", ") + a;
      fail(key_node,
           "unknown key '" + key + "' in " + what + "; expected one of: " + list);
    });
}

std::string
YamlReader::string(const YAML::Node& parent,
                   const std::string& key,
                   const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    fail(parent, what + " needs the key '" + key + "'");
  if (!node.IsScalar())
    fail(node, what + "." + key + " must be a string");
  return node.as<std::string>();
}

std::string
YamlReader::optionalString(const YAML::Node& parent,
                           const std::string& key,
                           const std::string& fallback,
                           const std::string& what) const
{
  return parent[key] ? string(parent, key, what) : fallback;
}

long long
YamlReader::integerValue(const YAML::Node& node,
                         long long min,
                         long long max,
                         const std::string& what) const
{
  long long v = 0;
  try {
    if (!node.IsScalar())
      throw YAML::BadConversion(node.Mark());
    v = node.as<long long>();
  } catch (const YAML::BadConversion&) {
    fail(node, what + " must be an integer");
  }
  if (v < min || v > max)
    fail(node, what + " = " + std::to_string(v) + " is out of range ["
                 + std::to_string(min) + ", " + std::to_string(max) + "]");
  return v;
}

double
YamlReader::realValue(const YAML::Node& node,
                      double min,
                      double max,
                      const std::string& what) const
{
  double v = 0.0;
  try {
    if (!node.IsScalar())
      throw YAML::BadConversion(node.Mark());
    v = node.as<double>();
  } catch (const YAML::BadConversion&) {
    fail(node, what + " must be a number");
  }
  if (!std::isfinite(v) || v < min || v > max) {
    std::ostringstream msg;
    msg << what << " = " << v << " is out of range [" << min << ", " << max << "]";
    fail(node, msg.str());
  }
  return v;
}

int
YamlReader::integer(const YAML::Node& parent,
                    const std::string& key,
                    int fallback,
                    int min,
                    int max,
                    const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    return fallback;
  return static_cast<int>(integerValue(node, min, max, what + "." + key));
}

double
YamlReader::real(const YAML::Node& parent,
                 const std::string& key,
                 double fallback,
                 double min,
                 double max,
                 const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    return fallback;
  return realValue(node, min, max, what + "." + key);
}

std::string
YamlReader::path(const YAML::Node& parent,
                 const std::string& key,
                 const std::string& what) const
{
  return resolve(string(parent, key, what));
}

std::string
YamlReader::resolve(const std::string& text) const
{
  if (text.empty() || fs::path(text).is_absolute())
    return text;
  return (fs::path(base_folder_) / text).lexically_normal().string();
}

} // namespace planar_grid
