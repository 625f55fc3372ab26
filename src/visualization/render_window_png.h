// SPDX-License-Identifier: BSD-3-Clause
// Private to the visualization library: one way to turn a render window into a PNG
// file.
#pragma once

#include <string>

class vtkRenderWindow;

namespace planar_grid {
namespace detail {

/** \brief Renders \a window, grabs its back buffer (RGB) and writes it as a PNG to
 * \a path atomically (temporary file, rename).
 * \throws planar_grid::IOError when the file cannot be written */
void saveRenderWindowPng(vtkRenderWindow* window, const std::string& path);

} // namespace detail
} // namespace planar_grid
