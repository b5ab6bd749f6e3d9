// The subcommands of `cpvs`: each registers its options on the CLI11 app and runs.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace cpvs::cli {

/// Each add* function adds a subcommand to `app` and sets its callback, which runs the
/// command and stores its exit status in `status`.
void addBakeCommand(CLI::App& app, int& status);
void addInspectCommand(CLI::App& app, int& status);
void addQueryCommand(CLI::App& app, int& status);
void addVerifyCommand(CLI::App& app, int& status);
void addRenderCommand(CLI::App& app, int& status);

}  // namespace cpvs::cli
