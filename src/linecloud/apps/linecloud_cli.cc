#include <cstdlib>
#include <iostream>

#include "linecloud/apps/commands.h"
#include "linecloud/lifting/key_store.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {

namespace {

// Every command, and the key store guarded from every output.
void RegisterCommands(CLI::App& app) {
  app.require_subcommand(1);
  // No command writes into the user's key store (a --out, --ply or cache
  // naming a key, directly or through a link): util/file.h.
  if (const char* home = std::getenv("HOME");
      (home && *home) || std::getenv("LINECLOUD_KEY_STORE")) {
    try {
      ProtectDirectory(KeyStore::DefaultDirectory());
    } catch (const Error&) {
    }
  }
  app.set_version_flag("--version", "linecloud 0.1.0");
  RegisterDemoCommand(app);
  RegisterMapCommand(app);
  RegisterLiftCommand(app);
  RegisterKeysCommand(app);
  RegisterInfoCommand(app);
  RegisterExportCommand(app);
  RegisterSolveCommand(app);
  RegisterLocalizeCommand(app);
  RegisterOptionsCommand(app);
  RegisterMakeQueryCommand(app);
  RegisterBenchCommand(app);
  RegisterEvalCommand(app);
  RegisterServeCommand(app);
  RegisterAttackCommand(app);
  RegisterAuditCommand(app);
}

// An unknown command word, named with the commands there are (CLI11 would
// take it for an extra argument).
bool RefuseUnknownCommand(const CLI::App& app, int argc, const char* const* argv) {
  if (argc < 2 || argv[1][0] == '-') return false;
  const std::string name = argv[1];
  std::string names;
  for (const CLI::App* sub : app.get_subcommands({})) {
    if (sub->get_name() == name) return false;
    names += (names.empty() ? "" : ", ") + sub->get_name();
  }
  std::cerr << "error: unknown command '" << name << "' (commands: " << names << ")\n";
  return true;
}

// Outputs named on the command line are checked before any work: one inside
// the key store (directly or through a link) is refused at once.
void CheckOutputsFirst(int argc, const char* const* argv) {
  for (int i = 1; i + 1 < argc; ++i) {
    const std::string_view flag = argv[i];
    if (flag != "--out" && flag != "--ply" && flag != "--overlay") continue;
    try {
      CheckNotProtected(argv[i + 1]);
    } catch (const Error& e) {
      Fail("{} {}", flag, e.what());
    }
  }
}

}  // namespace

int RunLinecloud(int argc, const char* const* argv) {
  CLI::App app{
      "linecloud: privacy-preserving image-based localization with line "
      "clouds (Speciale et al., CVPR 2019)",
      "linecloud"};
  RegisterCommands(app);
  if (RefuseUnknownCommand(app, argc, argv)) return 2;
  try {
    CheckOutputsFirst(argc, argv);
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "error: " << e.what() << " (run with --help for usage)\n";
    return 2;
  } catch (const Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    // The process boundary: nothing escapes as an abort.
    std::cerr << "error: internal: " << e.what() << "\n";
    return 1;
  } catch (...) {
    std::cerr << "error: internal: unknown exception\n";
    return 1;
  }
  return 0;
}

}  // namespace linecloud
