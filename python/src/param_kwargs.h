// SPDX-License-Identifier: BSD-3-Clause
// A class's parameters as Python keyword arguments, made from the algorithm's
// ParamDeclarations table: the constructor's arguments, their conversion and errors,
// the signature (docstring and inspect), and the params dict.
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_declaration.h>

#include <pybind11/pybind11.h>

#include <string>
#include <utility>
#include <variant>

namespace planar_grid {
namespace python {

namespace py = pybind11;

/** \brief A parameter value as a Python float, int, bool or str. */
inline py::object
paramToPython(const ParamValue& value)
{
  return std::visit([](const auto& v) -> py::object { return py::cast(v); }, value);
}

/** \brief The Python type name of a declared parameter (float, int, bool, str). */
template <typename Params>
const char*
paramPythonType(const ParamDeclaration<Params>& declaration)
{
  using Type = typename ParamDeclaration<Params>::Type;
  switch (declaration.type) {
    case Type::DOUBLE:
      return "float";
    case Type::INT:
      return "int";
    case Type::BOOL:
      return "bool";
    case Type::CHOICE:
      break;
  }
  return "str";
}

/** \brief \a params as a dict keyed by the table's keys, in the table's order. */
template <typename Params>
py::dict
paramsDict(const ParamDeclarations<Params>& table, const Params& params)
{
  py::dict dict;
  for (const auto& declaration : table)
    dict[declaration.key.c_str()] = paramToPython(declaration.get(params));
  return dict;
}

namespace detail {

/** \brief \a value converted as pybind11 converts an argument of type V.
 * \throws py::type_error naming the class and key when it does not convert */
template <typename V>
V
castArgument(const py::handle& value, const std::string& where, const char* type)
{
  py::detail::make_caster<V> caster;
  if (!caster.load(value, true))
    throw py::type_error(
      where + ": expected " + type + ", got "
      + py::str(py::type::of(value).attr("__name__")).template cast<std::string>());
  return py::detail::cast_op<V>(std::move(caster));
}

} // namespace detail

/** \brief Params from the keyword arguments: the defaults of a default-constructed
 * Params, each given key converted and set. The result is not range-checked (the
 * class's constructor does that).
 * \param[in] table the declarations
 * \param[in] kwargs the keyword arguments
 * \param[in] class_name the Python class, for messages
 * \throws py::type_error for a key that is no parameter or a value of another type;
 * py::value_error for a choice that is none of the names */
template <typename Params>
Params
paramsFromKwargs(const ParamDeclarations<Params>& table,
                 const py::kwargs& kwargs,
                 const std::string& class_name)
{
  using Type = typename ParamDeclaration<Params>::Type;
  Params params;
  std::size_t used = 0;
  for (const auto& declaration : table) {
    const char* key = declaration.key.c_str();
    if (!kwargs.contains(key))
      continue;
    ++used;
    const py::handle value = kwargs[key];
    const std::string where = class_name + ": " + declaration.key;
    const char* type = paramPythonType(declaration);
    ParamValue converted;
    switch (declaration.type) {
      case Type::DOUBLE:
        converted = detail::castArgument<double>(value, where, type);
        break;
      case Type::INT:
        converted = detail::castArgument<int>(value, where, type);
        break;
      case Type::BOOL:
        converted = detail::castArgument<bool>(value, where, type);
        break;
      case Type::CHOICE:
        converted = detail::castArgument<std::string>(value, where, type);
        break;
    }
    try {
      declaration.set(params, converted);
    } catch (const planar_grid::Exception& e) {
      throw py::value_error(where + ": " + e.what());
    }
  }
  if (used != kwargs.size())
    for (const auto& item : kwargs) {
      const std::string key = py::str(item.first).cast<std::string>();
      bool known = false;
      for (const auto& declaration : table)
        known = known || declaration.key == key;
      if (!known)
        throw py::type_error(class_name + "() got an unexpected keyword argument '"
                             + key + "'");
    }
  return params;
}

/** \brief The constructor's signature line, as pybind11 writes one (and stubgen reads
 * it): `__init__(self: QUALNAME, *, key: type = default, ...) -> None`. */
template <typename Params>
std::string
keywordSignature(const ParamDeclarations<Params>& table, const std::string& qualname)
{
  const Params defaults{};
  std::string text = "__init__(self: " + qualname + ", *";
  for (const auto& declaration : table)
    text +=
      ", " + declaration.key + ": " + paramPythonType(declaration) + " = "
      + py::repr(paramToPython(declaration.get(defaults))).template cast<std::string>();
  return text + ") -> None";
}

/** \brief The constructor's inspect.Signature (inspect cannot read pybind11's
 * docstring signatures): every key keyword-only, annotated, with its default. */
template <typename Params>
py::object
keywordSignatureObject(const ParamDeclarations<Params>& table)
{
  const Params defaults{};
  const py::module_ inspect = py::module_::import("inspect");
  const py::module_ builtins = py::module_::import("builtins");
  const py::object parameter = inspect.attr("Parameter");
  py::list parameters;
  for (const auto& declaration : table)
    parameters.append(
      parameter(declaration.key, parameter.attr("KEYWORD_ONLY"),
                py::arg("default") = paramToPython(declaration.get(defaults)),
                py::arg("annotation") = builtins.attr(paramPythonType(declaration))));
  return inspect.attr("Signature")(parameters);
}

} // namespace python
} // namespace planar_grid
