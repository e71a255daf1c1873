// The `linecloud` command line: one small file per subcommand, each only
// parsing options and calling the library.
#pragma once

#include <CLI/CLI.hpp>

namespace linecloud {

void RegisterDemoCommand(CLI::App& app);
void RegisterLiftCommand(CLI::App& app);
void RegisterInfoCommand(CLI::App& app);
void RegisterExportCommand(CLI::App& app);
void RegisterSolveCommand(CLI::App& app);
void RegisterLocalizeCommand(CLI::App& app);
void RegisterMakeQueryCommand(CLI::App& app);
void RegisterBenchCommand(CLI::App& app);
void RegisterEvalCommand(CLI::App& app);
void RegisterServeCommand(CLI::App& app);
void RegisterAttackCommand(CLI::App& app);
void RegisterAuditCommand(CLI::App& app);
void RegisterOptionsCommand(CLI::App& app);
void RegisterKeysCommand(CLI::App& app);
void RegisterMapCommand(CLI::App& app);

// Runs the CLI; returns the process exit code. Errors are printed to stderr
// as one line `error: ...`.
int RunLinecloud(int argc, const char* const* argv);

}  // namespace linecloud
