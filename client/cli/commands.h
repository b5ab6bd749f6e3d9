// The subcommands of `cpvs`: each registers its options on the CLI11 app and runs.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace cpvs::cli {

/// Each add* function adds a subcommand to `app` and sets its callback, which runs the
/// command and stores its exit status in `status`.
void addBakeCommand(CLI::App& app, int& status);
void addInspectCommand(CLI::App& app, int& status);
void addPlanCommand(CLI::App& app, int& status);
void addQueryCommand(CLI::App& app, int& status);
void addVerifyCommand(CLI::App& app, int& status);
void addRenderCommand(CLI::App& app, int& status);
/// `contact-sheet` (render_command.cpp): every version of a subscription in one picture.
void addContactSheetCommand(CLI::App& app, int& status);
/// `sun` (sun_command.cpp): the sun's place for a place on Earth and an instant.
void addSunCommand(CLI::App& app, int& status);
/// `accuracy` (accuracy_command.cpp): bakes at several resolutions and measures them.
void addAccuracyCommand(CLI::App& app, int& status);

/// The bake farm's subcommands (farm_commands.cpp). Each takes --server HOST:PORT,
/// --token (default $CPVS_TOKEN) and --ca FILE (TLS). Exit status: 0 success, 1 the job
/// failed or was cancelled, 2 bad input or a request the farm refused (bad argument,
/// unknown job, authentication, quota), 4 the farm could not be reached or failed.
void addSubmitCommand(CLI::App& app, int& status);
void addJobsCommand(CLI::App& app, int& status);
void addWatchCommand(CLI::App& app, int& status);
void addCancelCommand(CLI::App& app, int& status);
void addDownloadCommand(CLI::App& app, int& status);
/// `track create | list | cancel` and `subscribe`: sun tracks (farm_commands.cpp).
void addTrackCommand(CLI::App& app, int& status);
void addSubscribeCommand(CLI::App& app, int& status);

}  // namespace cpvs::cli
