// mandisym: head CT -> mandible -> asymmetry report. See README.md.
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/memory.h"
#include "liblog/library_log.h"
#include "pipeline/commands.h"

namespace {

void usage(std::ostream& o) {
  o << "mandisym " << ms::pipeline::version() << " - mandibular asymmetry from head CT\n\n"
    << "Usage: mandisym COMMAND [arguments] [options]\n\nCommands:\n";
  for (const auto* s : {&ms::pipeline::run_spec(), &ms::pipeline::batch_spec(), &ms::pipeline::compare_spec(), &ms::pipeline::inspect_spec(),
                        &ms::pipeline::orthanc_spec(), &ms::pipeline::phantom_spec()})
    o << "  " << s->name << std::string(10 - s->name.size(), ' ') << s->synopsis << "\n";
  o << "  version   Print the version.\n\n"
    << "mandisym COMMAND --help shows the options of a command.\n"
    << "Exit codes: 0 ok, 1 internal error, 2 usage, 3 input not found, 4 invalid input,\n"
    << "            5 no mandible found, 6 geometry failed, 7 cannot write output,\n"
    << "            8 result failed quality control (outputs written),\n"
    << "            9 batch/orthanc: some studies failed, 130 interrupted.\n";
}

}  // namespace

int main(int argc, char** argv) {
  ms::tune_allocator_for_volumes();
  ms::liblog::route_library_messages();
  std::vector<std::string> args(argv + 1, argv + argc);
  std::string command_line = "mandisym";
  for (const auto& a : args) command_line += " " + a;
  if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
    usage(std::cout);
    return args.empty() ? 2 : 0;
  }
  const std::string verb = args[0];
  args.erase(args.begin());
  try {
    if (verb == "version" || verb == "--version") {
      std::cout << "mandisym " << ms::pipeline::version() << std::endl;
      return 0;
    }
    const ms::cli::CommandSpec* spec = nullptr;
    if (verb == "run") spec = &ms::pipeline::run_spec();
    if (verb == "phantom") spec = &ms::pipeline::phantom_spec();
    if (verb == "inspect") spec = &ms::pipeline::inspect_spec();
    if (verb == "compare") spec = &ms::pipeline::compare_spec();
    if (verb == "batch") spec = &ms::pipeline::batch_spec();
    if (verb == "orthanc") spec = &ms::pipeline::orthanc_spec();
    if (!spec) throw ms::Error(ms::ExitCode::Usage, "unknown command '" + verb + "' (see mandisym --help)");
    const ms::cli::Args parsed = ms::cli::parse(*spec, args);
    if (parsed.has("help")) {
      std::cout << ms::cli::help(*spec);
      return 0;
    }
    if (verb == "run") return ms::pipeline::run_command(parsed, command_line);
    if (verb == "inspect") return ms::pipeline::inspect_command(parsed);
    if (verb == "compare") return ms::pipeline::compare_command(parsed);
    if (verb == "batch") return ms::pipeline::batch_command(parsed);
    if (verb == "orthanc") return ms::pipeline::orthanc_command(parsed);
    return ms::pipeline::phantom_command(parsed);
  } catch (const ms::Error& e) {
    std::cerr << "mandisym: error: " << e.what() << std::endl;
    return static_cast<int>(e.code());
  } catch (const std::bad_alloc&) {
    std::cerr << "mandisym: error: out of memory" << std::endl;
    return static_cast<int>(ms::ExitCode::Internal);
  } catch (const std::exception& e) {
    std::cerr << "mandisym: internal error: " << e.what() << std::endl;
    return static_cast<int>(ms::ExitCode::Internal);
  }
}

const char* ms::pipeline::version() { return MANDISYM_VERSION; }
