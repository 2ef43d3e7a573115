// mandisym: head CT -> mandible -> asymmetry report. See README.md.
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "core/error.h"
#include "pipeline/commands.h"

namespace {

void usage(std::ostream& o) {
  o << "mandisym " << ms::pipeline::version() << " - mandibular asymmetry from head CT\n\n"
    << "Usage: mandisym COMMAND [arguments] [options]\n\nCommands:\n";
  for (const auto* s : {&ms::pipeline::run_spec(), &ms::pipeline::batch_spec(), &ms::pipeline::compare_spec(), &ms::pipeline::inspect_spec(),
                        &ms::pipeline::phantom_spec()})
    o << "  " << s->name << std::string(10 - s->name.size(), ' ') << s->synopsis << "\n";
  o << "  version   Print the version.\n\n"
    << "mandisym COMMAND --help shows the options of a command.\n"
    << "Exit codes: 0 ok, 1 internal error, 2 usage, 3 input not found, 4 invalid input,\n"
    << "            5 no mandible found, 6 geometry failed, 7 cannot write output,\n"
    << "            9 batch: some studies failed (cohort.csv), 130 interrupted.\n";
}

// The stages allocate and free volume-sized arrays (64 MB each at 512^2 x
// 300) dozens of times. glibc serves every block above 32 MB from a fresh
// mmap that the kernel zeroes page by page (7 % of a run's CPU under perf);
// from the heap, a freed array is reused as it is. Measured at 512^2 x 300:
// segment 4.1-4.2 -> 3.3-3.5 s, peak RSS 1.11 -> 1.33-1.40 GB
// (docs/benchmarks.md). Results do not depend on it.
void reuse_freed_memory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_MAX, 0);                // large blocks from the heap, not one mmap each
  mallopt(M_TRIM_THRESHOLD, 512 << 20);  // keep up to 512 MB freed at the heap's top
#endif
}

}  // namespace

int main(int argc, char** argv) {
  reuse_freed_memory();
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
