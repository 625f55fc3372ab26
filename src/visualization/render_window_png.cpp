// SPDX-License-Identifier: BSD-3-Clause
#include "render_window_png.h"

#include <planar_grid/core/atomic_file.h>

#include <vtkNew.h>
#include <vtkPNGWriter.h>
#include <vtkRenderWindow.h>
#include <vtkWindowToImageFilter.h>

namespace planar_grid {
namespace detail {

void
saveRenderWindowPng(vtkRenderWindow* window, const std::string& path)
{
  window->Render();
  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff(); // the back buffer holds the frame just rendered
  grab->Update();
  writeFileAtomically(path, [&grab](const std::string& tmp_path) {
    vtkNew<vtkPNGWriter> writer;
    writer->SetFileName(tmp_path.c_str());
    writer->SetInputConnection(grab->GetOutputPort());
    writer->Write();
    return writer->GetErrorCode() == 0;
  });
}

} // namespace detail
} // namespace planar_grid
