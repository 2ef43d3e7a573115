// The verbs of the mandisym executable.
#pragma once

#include <string>
#include <vector>

#include "pipeline/cli.h"

namespace ms::pipeline {

const cli::CommandSpec& run_spec();
const cli::CommandSpec& phantom_spec();
const cli::CommandSpec& inspect_spec();
const cli::CommandSpec& compare_spec();
const cli::CommandSpec& batch_spec();
const cli::CommandSpec& orthanc_spec();

// Each returns the process exit code; errors are thrown as ms::Error.
int run_command(const cli::Args& args, const std::string& command_line);
int phantom_command(const cli::Args& args);
int inspect_command(const cli::Args& args);
int compare_command(const cli::Args& args);
int batch_command(const cli::Args& args);
int orthanc_command(const cli::Args& args);

const char* version();

// Checks run's option values (ranges, combinations) as `run` would before
// reading anything; throws ms::Error(Usage) naming the option. `batch` calls
// it on the options it passes to every study.
void check_run_options(const cli::Args& args);

}  // namespace ms::pipeline
