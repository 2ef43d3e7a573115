#include "liblog/library_log.h"

#include <itkObjectFactory.h>
#include <itkOutputWindow.h>
#include <vtkLogger.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkSmartPointer.h>

#include <mutex>

namespace ms::liblog {
namespace {

// At most this many messages are held: a library that repeats one warning
// per voxel must not grow the store without bound.
constexpr std::size_t kMaxMessages = 200;

std::mutex g_mutex;
std::vector<std::string> g_messages;
std::size_t g_dropped = 0;

void hold(const char* origin, const char* text) {
  std::string line = std::string(origin) + ": " + (text ? text : "");
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  for (char& c : line)
    if (c == '\n' || c == '\r') c = ' ';
  std::lock_guard<std::mutex> lock(g_mutex);
  if (g_messages.size() < kMaxMessages) g_messages.push_back(std::move(line));
  else ++g_dropped;
}

class VtkSink : public vtkOutputWindow {
 public:
  static VtkSink* New();
  vtkTypeMacro(VtkSink, vtkOutputWindow);
  void DisplayText(const char* text) override { hold("VTK", text); }
};
vtkStandardNewMacro(VtkSink);

class ItkSink : public itk::OutputWindow {
 public:
  using Self = ItkSink;
  using Pointer = itk::SmartPointer<Self>;
  itkNewMacro(Self);
  void DisplayText(const char* text) override { hold("ITK", text); }
};

}  // namespace

void route_library_messages() {
  vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
  auto vtk_sink = vtkSmartPointer<VtkSink>::New();
  vtkOutputWindow::SetInstance(vtk_sink);
  itk::OutputWindow::SetInstance(ItkSink::New());
}

std::vector<std::string> take_library_messages() {
  std::lock_guard<std::mutex> lock(g_mutex);
  std::vector<std::string> out;
  out.swap(g_messages);
  if (g_dropped > 0) out.push_back("(" + std::to_string(g_dropped) + " further library messages not kept)");
  g_dropped = 0;
  return out;
}

}  // namespace ms::liblog
