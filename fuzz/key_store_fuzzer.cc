// Fuzzes the readers of the key store's files from outside: a release ledger
// (byte 0 of the input = 0) and a key bundle from `linecloud keys export`
// (byte 0 = 1, imported into a fresh store). Any input must parse or throw
// linecloud::Error — never crash, hang or over-allocate.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <sodium.h>
#include <unistd.h>

#include "linecloud/lifting/key_store.h"
#include "linecloud/lifting/release_ledger.h"
#include "linecloud/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  // Both files end in a BLAKE2b-256 of the rest: set it right, so that
  // mutations reach the parser behind the checksum.
  std::string input(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (input.size() >= 32) {
    crypto_generichash(reinterpret_cast<unsigned char*>(input.data()) + input.size() - 32, 32,
                       reinterpret_cast<const unsigned char*>(input.data()), input.size() - 32,
                       nullptr, 0);
  }
  static const std::string dir = [] {
    std::string d = (std::filesystem::temp_directory_path() /
                     ("linecloud_key_fuzz_" + std::to_string(::getpid())))
                        .string();
    std::filesystem::create_directories(d);
    std::filesystem::permissions(d, std::filesystem::perms::owner_all);
    return d;
  }();
  const std::string file = dir + "/input";
  std::ofstream(file, std::ios::binary)
      .write(input.data(), static_cast<std::streamsize>(input.size()));
  try {
    if (data[0] % 2 == 0) {
      const linecloud::ReleaseLedger ledger = linecloud::ReadLedger(file);
      if (ledger.sketch.size() != ledger.lines.size()) __builtin_trap();
    } else {
      const std::string store = dir + "/store";
      std::filesystem::remove_all(store);
      const linecloud::KeyStore keys(store);
      const linecloud::KeyStore::Lock lock = keys.LockExclusive();
      (void)keys.ImportEntry(file, true);
    }
  } catch (const linecloud::Error&) {
  }
  return 0;
}
