// Base64 decoding of a client-features body's descriptors (13 212 x 128
// bytes, 2.2 MB of text): our table decoder against libsodium's constant-time
// one (the previous implementation), same input, one thread.
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <sodium.h>

#include "linecloud/util/base64.h"

namespace linecloud {
namespace {

const std::string& Text() {
  static const std::string text = [] {
    std::mt19937 rng(3);
    std::vector<uint8_t> bytes(13212 * 128);
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    return Base64Encode(bytes);
  }();
  return text;
}

void BM_Base64DecodeTable(benchmark::State& state) {
  const std::string& text = Text();
  for (auto _ : state) benchmark::DoNotOptimize(Base64Decode(text, "descriptors"));
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(text.size()));
}
BENCHMARK(BM_Base64DecodeTable)->Unit(benchmark::kMillisecond);

void BM_Base64DecodeSodium(benchmark::State& state) {
  const std::string& text = Text();
  std::string out(text.size() / 4 * 3 + 3, '\0');
  for (auto _ : state) {
    size_t len = 0;
    sodium_base642bin(reinterpret_cast<unsigned char*>(out.data()), out.size(), text.data(),
                      text.size(), " \n\r", &len, nullptr, sodium_base64_VARIANT_ORIGINAL);
    benchmark::DoNotOptimize(len);
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(text.size()));
}
BENCHMARK(BM_Base64DecodeSodium)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace linecloud
