// SPDX-License-Identifier: BSD-3-Clause
// A class's parameters as Python keyword arguments, made from the algorithm's
// ParamDeclarations table: the constructor's arguments, their conversion and errors,
// the signature (docstring and inspect), and the params dict.
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_declaration.h>

#include <pybind11/pybind11.h>

#include <cstddef>
#include <functional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace planar_grid {
namespace python {

namespace py = pybind11;

/** \brief \a text wrapped at word boundaries into lines of at most \a width characters
 * after \a indent spaces (docstrings; planar_grid_python.h). */
std::string wrapText(const std::string& text, std::size_t indent, std::size_t width);

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

/** \brief A parameter outside the class's declared table that the constructor takes
 * first, by position or by name, without a default (the stereo rig of an occupancy
 * filter): a float read-write property. */
template <typename T> struct LeadingParam {
  /** \brief The property's and the argument's name. */
  std::string key;
  /** \brief Meaning, unit and range (the numpydoc entry and the property's doc). */
  std::string description;
  /** \brief Reads the value. */
  std::function<double(const T&)> get;
  /** \brief Writes the value (the object's check runs after it). */
  std::function<void(T&, double)> set;
};

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

/** \brief \a value converted to \a declaration's type, as pybind11 converts an
 * argument of that type (a float takes an int; an int no float).
 * \throws py::type_error naming \a where when it does not convert */
template <typename Params>
ParamValue
convertArgument(const ParamDeclaration<Params>& declaration,
                const py::handle& value,
                const std::string& where)
{
  using Type = typename ParamDeclaration<Params>::Type;
  const char* type = paramPythonType(declaration);
  switch (declaration.type) {
    case Type::DOUBLE:
      return detail::castArgument<double>(value, where, type);
    case Type::INT:
      return detail::castArgument<int>(value, where, type);
    case Type::BOOL:
      return detail::castArgument<bool>(value, where, type);
    case Type::CHOICE:
      break;
  }
  return detail::castArgument<std::string>(value, where, type);
}

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
                 const py::dict& kwargs,
                 const std::string& class_name)
{
  Params params;
  std::size_t used = 0;
  for (const auto& declaration : table) {
    const char* key = declaration.key.c_str();
    if (!kwargs.contains(key))
      continue;
    ++used;
    const std::string where = class_name + ": " + declaration.key;
    const ParamValue converted = convertArgument(declaration, kwargs[key], where);
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

/** \brief \a unit spelled out for a docstring: meters for m, radians for rad,
 * pixels for px, seconds for s; another unit as it is. */
inline std::string
unitWord(const std::string& unit)
{
  if (unit == "m")
    return "meters";
  if (unit == "rad")
    return "radians";
  if (unit == "px")
    return "pixels";
  if (unit == "s")
    return "seconds";
  return unit;
}

/** \brief The numpydoc "Parameters" entries of the constructor's keyword arguments,
 * one per declaration in the table's order: `key : type, optional` (a choice's type
 * is the set of its names), then the
 * description, "Default X." (the default-constructed Params' value) and, for a
 * number, its unit and range; each description indented by four spaces, in lines of
 * at most 88 characters. */
template <typename Params>
std::string
declaredParameterDocs(const ParamDeclarations<Params>& table)
{
  using Type = typename ParamDeclaration<Params>::Type;
  const Params defaults{};
  std::string out;
  for (const auto& declaration : table) {
    std::string text =
      declaration.description + " Default "
      + py::repr(paramToPython(declaration.get(defaults))).template cast<std::string>()
      + ".";
    if (declaration.type == Type::DOUBLE || declaration.type == Type::INT) {
      const std::string unit = unitWord(declaration.unit);
      text += " In " + formatParamRange(declaration.range)
              + (unit.empty() ? std::string() : " " + unit) + ".";
    }
    std::string type = paramPythonType(declaration);
    if (declaration.type == Type::CHOICE) {
      type.clear();
      for (const auto& choice : declaration.choices)
        type += (type.empty() ? "{'" : ", '") + choice + "'";
      type += "}";
    }
    out += declaration.key + " : " + type + ", optional\n" + wrapText(text, 4, 88);
  }
  return out;
}

/** \brief The constructor's signature line, as pybind11 writes one (and stubgen reads
 * it): `__init__(self: QUALNAME, *, key: type = default, ...) -> None`. */
template <typename Params>
std::string
keywordSignature(const ParamDeclarations<Params>& table,
                 const std::string& qualname,
                 const std::vector<std::string>& leading = {})
{
  const Params defaults{};
  std::string text = "__init__(self: " + qualname;
  for (const auto& key : leading)
    text += ", " + key + ": float";
  text += ", *";
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
keywordSignatureObject(const ParamDeclarations<Params>& table,
                       const std::vector<std::string>& leading = {})
{
  const Params defaults{};
  const py::module_ inspect = py::module_::import("inspect");
  const py::module_ builtins = py::module_::import("builtins");
  const py::object parameter = inspect.attr("Parameter");
  py::list parameters;
  for (const auto& key : leading)
    parameters.append(parameter(key, parameter.attr("POSITIONAL_OR_KEYWORD"),
                                py::arg("annotation") = builtins.attr("float")));
  for (const auto& declaration : table)
    parameters.append(
      parameter(declaration.key, parameter.attr("KEYWORD_ONLY"),
                py::arg("default") = paramToPython(declaration.get(defaults)),
                py::arg("annotation") = builtins.attr(paramPythonType(declaration))));
  return inspect.attr("Signature")(parameters);
}

/** \brief The values of the leading arguments, \a args by position then the rest of
 * their keys popped from \a kwargs.
 * \throws py::type_error for too many positional arguments, a key given twice or one
 * missing, or a value that is no float */
template <typename T>
std::vector<double>
takeLeadingArguments(const std::vector<LeadingParam<T>>& leading,
                     const py::args& args,
                     py::dict& kwargs,
                     const std::string& class_name)
{
  if (args.size() > leading.size())
    throw py::type_error(class_name + "() takes " + std::to_string(leading.size())
                         + " positional arguments but " + std::to_string(args.size())
                         + " were given");
  std::vector<double> values;
  for (std::size_t i = 0; i < leading.size(); ++i) {
    const std::string& key = leading[i].key;
    const std::string where = class_name + ": " + key;
    if (i < args.size()) {
      if (kwargs.contains(key))
        throw py::type_error(class_name + "() got multiple values for argument '" + key
                             + "'");
      values.push_back(detail::castArgument<double>(args[i], where, "float"));
    } else if (kwargs.contains(key)) {
      values.push_back(
        detail::castArgument<double>(kwargs[key.c_str()], where, "float"));
      PyDict_DelItemString(kwargs.ptr(), key.c_str());
    } else
      throw py::type_error(class_name + "() missing required argument: '" + key + "'");
  }
  return values;
}

/** \brief Binds the constructor of \a cls from \a table: it takes the \a leading keys
 * first, by position or by name, then every key of the table as a keyword argument
 * with the C++ default (paramsFromKwargs()), and returns \a make of the Params and the
 * leading values; its docstring starts with the signature line (keywordSignature()),
 * then \a summary, and the class gets its inspect.Signature.
 * \param[in] cls the class
 * \param[in] class_name the Python name, for messages and the signature
 * \param[in] table the declarations (a static table: the binding keeps a reference)
 * \param[in] leading the arguments before the table's (none for most classes)
 * \param[in] make (const Params&, const std::vector<double>& leading values) ->
 * Holder, which checks the values as the class does
 * \param[in] summary the docstring after the signature line */
template <typename T, typename Holder, typename Params, typename Make>
void
bindKeywordConstructor(py::class_<T, Holder>& cls,
                       const std::string& class_name,
                       const ParamDeclarations<Params>& table,
                       const std::vector<LeadingParam<T>>& leading,
                       Make make,
                       const std::string& summary)
{
  std::vector<std::string> keys;
  for (const auto& param : leading)
    keys.push_back(param.key);
  const std::string doc =
    keywordSignature(table, "planar_grid._planar_grid." + class_name, keys) + "\n\n"
    + summary;
  {
    py::options options;
    options.disable_function_signatures();
    cls.def(py::init([class_name, &table, leading, make](const py::args& args,
                                                         const py::kwargs& kwargs) {
              py::dict rest(kwargs);
              const std::vector<double> values =
                takeLeadingArguments(leading, args, rest, class_name);
              return make(paramsFromKwargs(table, rest, class_name), values);
            }),
            doc.c_str());
  }
  cls.attr("__signature__") = keywordSignatureObject(table, keys);
}

/** \brief Binds an algorithm's declared parameters on its Python class \a cls: a
 * read-write property per key (type, meaning, unit and range in its docstring), a
 * constructor taking them as keyword arguments with the C++ defaults, __signature__
 * and __repr__ (a constructor call that rebuilds the object). A value out of its
 * declared range, or one \a object_check refuses, raises ValueError and leaves the
 * object as it was.
 * \param[in] cls the class (T held by Holder, default-constructible)
 * \param[in] class_name the Python name, for messages and repr
 * \param[in] table the declarations (a static table: the bindings keep a reference)
 * \param[in] get_params T -> const Params& (T::getParams)
 * \param[in] set_params (T&, const Params&) (T::setParams)
 * \param[in] leading parameters outside the table that the constructor takes first,
 * each a float property too (the stereo rig of an occupancy filter)
 * \param[in] object_check const T& -> nullptr or what is wrong, run after every write
 * (the class's own check of what the table's ranges do not say; none by default) */
template <typename T, typename Holder, typename Params, typename Get, typename Set>
void
bindDeclaredParams(py::class_<T, Holder>& cls,
                   const std::string& class_name,
                   const ParamDeclarations<Params>& table,
                   Get get_params,
                   Set set_params,
                   const std::vector<LeadingParam<T>>& leading = {},
                   std::function<const char*(const T&)> object_check = nullptr)
{
  // The declared ranges, checked before a value reaches the object, then the object's
  // own check after it.
  const auto check = [class_name, &table](const Params& params) {
    const std::string bad = checkDeclaredRanges(table, params);
    if (!bad.empty())
      throw py::value_error(class_name + ": invalid parameter: " + bad);
  };
  const auto checkObject = [class_name, object_check](const T& object) {
    const char* bad = object_check ? object_check(object) : nullptr;
    if (bad != nullptr)
      throw py::value_error(class_name + ": invalid parameter: " + bad);
  };
  for (const auto& param : leading)
    cls.def_property(
      param.key.c_str(), param.get,
      [param, checkObject](T& object, double value) {
        const double old = param.get(object);
        param.set(object, value);
        try {
          checkObject(object);
        } catch (const py::value_error&) {
          param.set(object, old);
          throw;
        }
      },
      ("float: " + param.description).c_str());
  for (const auto& declaration : table) {
    using Type = typename ParamDeclaration<Params>::Type;
    const bool numeric =
      declaration.type == Type::DOUBLE || declaration.type == Type::INT;
    const std::string doc =
      std::string(paramPythonType(declaration)) + ": " + declaration.description
      + (numeric ? " In " + formatParamRange(declaration.range, declaration.unit) + "."
                 : std::string());
    cls.def_property(
      declaration.key.c_str(),
      [declaration, get_params](const T& object) {
        return paramToPython(declaration.get(get_params(object)));
      },
      [declaration, get_params, set_params, class_name, check,
       checkObject](T& object, const py::object& value) {
        const Params old = get_params(object);
        Params params = old;
        const std::string where = class_name + ": " + declaration.key;
        const ParamValue converted = convertArgument(declaration, value, where);
        try {
          declaration.set(params, converted);
        } catch (const planar_grid::Exception& e) {
          throw py::value_error(where + ": " + e.what());
        }
        check(params);
        set_params(object, params);
        try {
          checkObject(object);
        } catch (const py::value_error&) {
          set_params(object, old);
          throw;
        }
      },
      doc.c_str());
  }
  std::string docs;
  for (const auto& param : leading)
    docs += param.key + " : float\n" + wrapText(param.description, 4, 88);
  bindKeywordConstructor(
    cls, class_name, table, leading,
    [check, checkObject, set_params, leading](const Params& params,
                                              const std::vector<double>& values) {
      check(params);
      Holder object(new T());
      set_params(*object, params);
      for (std::size_t i = 0; i < leading.size(); ++i)
        leading[i].set(*object, values[i]);
      checkObject(*object);
      return object;
    },
    std::string(leading.empty() ? "Every keyword argument is a parameter (the "
                                  "properties), with the C++ default.\n\n"
                                : "The leading arguments come first, by position or "
                                  "by name; every other argument is a keyword, with "
                                  "the C++ default. All are properties.\n\n")
      + "Parameters\n----------\n" + docs + declaredParameterDocs(table));
  cls.def("__repr__", [class_name, &table, get_params, leading](const T& object) {
    std::string text = "planar_grid." + class_name + "(";
    const char* separator = "";
    for (const auto& param : leading) {
      text += separator + param.key + "="
              + py::repr(py::float_(param.get(object))).template cast<std::string>();
      separator = ", ";
    }
    const Params& params = get_params(object);
    for (const auto& declaration : table) {
      text +=
        separator + declaration.key + "="
        + py::repr(paramToPython(declaration.get(params))).template cast<std::string>();
      separator = ", ";
    }
    return text + ")";
  });
}

} // namespace python
} // namespace planar_grid
