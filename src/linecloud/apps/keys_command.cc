#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/lifting/key_store.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

struct KeysArgs {
  std::string model_dir, bundle, key_store;
  bool replace_ledger = false;
};

KeyStore StoreOf(const KeysArgs& a) {
  return KeyStore(a.key_store.empty() ? KeyStore::DefaultDirectory() : a.key_store);
}

void RunExport(const KeysArgs& a) {
  const KeyStore store = StoreOf(a);
  const KeyStore::Lock lock = store.LockExclusive();
  const Reconstruction model = ReadColmapModel(a.model_dir);
  const std::optional<KeyStoreMatch> known = store.Find(ModelSketchElements(model));
  if (!known) {
    Fail("{}: the key store {} has no key for this model (lift it first)", a.model_dir,
         store.dir());
  }
  store.ExportEntry(known->key.Fingerprint(), a.bundle);
  std::cout << fmt::format(
      "exported key {} of {} with its release ledger -> {} (mode 0600: as secret as the key; "
      "`linecloud keys import {}` on the other machine)\n",
      ToHex(known->key.Fingerprint()), a.model_dir, a.bundle, a.bundle);
}

void RunImport(const KeysArgs& a) {
  const KeyStore store = StoreOf(a);
  const KeyStore::Lock lock = store.LockExclusive();
  std::cout << fmt::format("imported into {}: {}\n", store.dir(),
                           store.ImportEntry(a.bundle, a.replace_ledger));
}

}  // namespace

void RegisterKeysCommand(CLI::App& app) {
  auto args = std::make_shared<KeysArgs>();
  CLI::App* keys = app.add_subcommand(
      "keys", "Move a model's key and release ledger between key stores (one place, one key)");
  keys->require_subcommand(1);
  CLI::App* out = keys->add_subcommand(
      "export", "Write the key store's entry of a model (key, registration, ledger) to one file");
  out->add_option("--model", args->model_dir, "COLMAP model whose key to export")->required();
  out->add_option("--out", args->bundle, "Bundle file to write (mode 0600)")->required();
  out->add_option("--key-store", args->key_store, "Key store (default: as lift's)");
  out->callback([args] { RunExport(*args); });
  CLI::App* in = keys->add_subcommand(
      "import", "Install a bundle from `keys export` into this machine's key store");
  in->add_option("bundle", args->bundle, "Bundle file from `linecloud keys export`")->required();
  in->add_option("--key-store", args->key_store, "Key store (default: as lift's)");
  in->add_flag("--replace-ledger", args->replace_ledger,
               "Take the bundle's release ledger over a different one already here");
  in->callback([args] { RunImport(*args); });
}

}  // namespace linecloud
