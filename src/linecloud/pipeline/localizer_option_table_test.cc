#include "linecloud/pipeline/localizer_option_table.h"

#include <cctype>
#include <set>

#include <gtest/gtest.h>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(LocalizerOptionTable, NamesFlagsAndDefaultsAreConsistent) {
  std::set<std::string> names, flags;
  const LocalizerOptions defaults;
  const json all = LocalizerOptionsToJson(defaults);
  for (const OptionSpec& s : LocalizerOptionTable()) {
    EXPECT_TRUE(names.insert(s.name).second) << s.name;
    EXPECT_TRUE(flags.insert(s.Flag()).second) << s.Flag();
    for (const char c : s.name) EXPECT_TRUE(std::islower(c) || c == '_') << s.name;
    EXPECT_FALSE(s.help.empty()) << s.name;
    EXPECT_EQ(all.at(s.name), s.Default()) << s.name;
    EXPECT_EQ(FindLocalizerOption(s.name), &s);
    // Setting the default changes nothing.
    LocalizerOptions o;
    SetLocalizerOption(&o, s, s.Default(), "test");
    EXPECT_EQ(LocalizerOptionsToJson(o), all) << s.name;
    if (s.type == OptionType::kInteger || s.type == OptionType::kNumber) {
      const json d = s.Default();
      if (!d.is_null()) {
        EXPECT_TRUE(d.get<double>() >= s.min && d.get<double>() <= s.max) << s.name;
      }
    }
  }
  EXPECT_EQ(FindLocalizerOption("no_such_option"), nullptr);
  // The switches on by default are turned off by --no-NAME.
  EXPECT_EQ(FindLocalizerOption("refine")->Flag(), "--no-refine");
  EXPECT_EQ(FindLocalizerOption("refine_focal")->Flag(), "--refine-focal");
  EXPECT_EQ(FindLocalizerOption("max_ratio")->Flag(), "--max-ratio");
}

TEST(LocalizerOptionTable, ValuesReachTheirMembers) {
  LocalizerOptions o;
  const auto set = [&](const char* name, const json& v) {
    SetLocalizerOption(&o, *FindLocalizerOption(name), v, "test");
  };
  set("threshold", 2.5);
  set("seed", 9);
  set("max_iterations", 321);
  set("uniform_sampling", true);
  set("refine", false);
  set("min_inliers", 17);
  set("max_ratio", 0.7);
  set("features", "opencv");
  set("index", "flann");
  set("threads", 3);
  set("map_gravity", "0,0,-2");
  EXPECT_EQ(o.localize.ransac.max_error, 2.5);
  EXPECT_EQ(o.localize.ransac.seed, 9u);
  EXPECT_EQ(o.localize.ransac.max_iterations, 321);
  EXPECT_FALSE(o.localize.ransac.progressive_sampling);
  EXPECT_FALSE(o.localize.refine);
  EXPECT_EQ(o.localize.success.min_inliers_points, 17);
  EXPECT_EQ(o.localize.success.min_inliers_lines, 17);
  EXPECT_EQ(o.image.matching.max_ratio, 0.7);
  EXPECT_EQ(o.image.sift.extractor, SiftExtractor::kOpenCV);
  EXPECT_EQ(o.image.index.kind, DescriptorIndexKind::kFlann);
  EXPECT_EQ(o.image.threads, 3);
  EXPECT_EQ(o.image.index.threads, 3);
  ASSERT_TRUE(o.map_gravity);
  EXPECT_EQ(*o.map_gravity, Eigen::Vector3d(0, 0, -2));
  // null: back to "the method's" inlier counts and "the map's" gravity.
  set("min_inliers", nullptr);
  EXPECT_EQ(o.localize.success.min_inliers_points, SuccessCriteria{}.min_inliers_points);
  EXPECT_EQ(o.localize.success.min_inliers_lines, SuccessCriteria{}.min_inliers_lines);
  set("map_gravity", nullptr);
  EXPECT_FALSE(o.map_gravity);
  // exact_matching is approximate_from 0, and turned off gives the default back.
  set("exact_matching", true);
  EXPECT_EQ(o.image.approximate_from, 0u);
  set("exact_matching", false);
  EXPECT_EQ(o.image.approximate_from, ImageQueryOptions{}.approximate_from);
  o.Check();
}

TEST(LocalizerOptionTable, BadValuesNameTheOptionAndItsRange) {
  LocalizerOptions o;
  const auto error = [&](const char* name, const json& v) {
    return ErrorOf([&] { SetLocalizerOption(&o, *FindLocalizerOption(name), v, "body"); });
  };
  EXPECT_EQ(error("max_ratio", 1.5), "body: max_ratio must be a number in (0, 1], got 1.5");
  EXPECT_EQ(error("max_ratio", 0), "body: max_ratio must be a number in (0, 1], got 0");
  EXPECT_EQ(error("max_iterations", 2.5),
            "body: max_iterations must be a whole number in [1, 10000000], got 2.5");
  EXPECT_EQ(error("seed", -1), "body: seed must be a whole number in [0, 2^53], got -1");
  EXPECT_EQ(error("refine", "yes"), "body: refine must be true or false, got \"yes\"");
  EXPECT_EQ(error("features", "sift"),
            "body: features must be one of colmap, opencv, got \"sift\"");
  EXPECT_EQ(error("threshold", nullptr),
            "body: threshold must be a number in (0, 10000], got null");
  EXPECT_NE(error("map_gravity", json{0, 0, 0}).find("non-zero direction"), std::string::npos);
  EXPECT_NE(error("map_gravity", json{1, 2}).find("map_gravity must be"), std::string::npos);
  // Text (flags, multipart parts): whole strings only.
  const OptionSpec& threshold = *FindLocalizerOption("threshold");
  EXPECT_EQ(ParseOptionText(threshold, "3.5", "x"), json(3.5));
  EXPECT_NE(ErrorOf([&] {
              ParseOptionText(threshold, "3.5px", "--threshold");
            }).find("--threshold: threshold must be"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ParseOptionText(threshold, "", "x"); }), "");
  EXPECT_NE(ErrorOf([&] { ParseOptionText(threshold, " 3", "x"); }), "");
  // Text means what JSON means: no hex, signs, bare dots, nan, 1/0 for switches.
  for (const char* text : {"0x10", "+3", "3.", ".5", "nan", "inf", "3 ", "1e400"}) {
    EXPECT_NE(ErrorOf([&] {
                LocalizerOptions o;
                SetLocalizerOption(&o, threshold, ParseOptionText(threshold, text, "x"), "x");
              }),
              "")
        << text;
  }
  EXPECT_NE(ErrorOf([&] { ParseOptionText(*FindLocalizerOption("refine"), "1", "x"); }), "");
  // Whole numbers are checked exactly (2^53 + 1 is not rounded into the range).
  EXPECT_NE(error("seed", json(uint64_t{9007199254740993u})).find("seed must be"),
            std::string::npos);
  EXPECT_EQ(error("seed", json(uint64_t{9007199254740992u})), "");
  EXPECT_EQ(error("seed", 0), "");  // back to the default for the check below
  // Errors show a bad value escaped and cut short.
  EXPECT_EQ(error("features", std::string(1 << 20, 'x')).size(), 130u);  // 50 + 80
  EXPECT_EQ(error("features", std::string("a\0b", 3)),
            "body: features must be one of colmap, opencv, got \"a\\u0000b\"");
  EXPECT_EQ(ParseOptionText(*FindLocalizerOption("refine"), "false", "x"), json(false));
  EXPECT_EQ(ParseOptionText(*FindLocalizerOption("min_inliers"), "null", "x"), json());
  EXPECT_EQ(ParseOptionText(*FindLocalizerOption("map_gravity"), "0,-1,0", "x"),
            (json{0.0, -1.0, 0.0}));
  // Nothing was changed by the refused values.
  EXPECT_EQ(LocalizerOptionsToJson(o), LocalizerOptionsToJson(LocalizerOptions{}));
}

TEST(LocalizerOptionTable, AnObjectOfOptionsKeepsToItsScopes) {
  LocalizerOptions o;
  constexpr OptionScope kRequest[] = {OptionScope::kRequest};
  SetLocalizerOptions(&o, {{"threshold", 3}, {"seed", 4}}, kRequest, "body");
  EXPECT_EQ(o.localize.ransac.max_error, 3);
  EXPECT_EQ(o.localize.ransac.seed, 4u);
  EXPECT_EQ(ErrorOf([&] {
              SetLocalizerOptions(&o, {{"features", "opencv"}}, kRequest, "body");
            }),
            "body: 'features' is fixed when the map is loaded, not set per request");
  const std::string unknown = ErrorOf([&] {
    SetLocalizerOptions(&o, {{"thresold", 3}}, kRequest, "body");
  });
  EXPECT_NE(unknown.find("body: unknown option \"thresold\" (known: threshold, seed"),
            std::string::npos)
      << unknown;
  EXPECT_EQ(unknown.find("features"), std::string::npos) << "only this scope's names";
  constexpr std::string_view kOwn[] = {"camera"};
  SetLocalizerOptions(&o, {{"camera", "ignored here"}, {"seed", 5}}, kRequest, "body", kOwn);
  EXPECT_EQ(o.localize.ransac.seed, 5u);
  // The table as data: every option once, with its scope and default.
  const json table = LocalizerOptionTableJson();
  ASSERT_EQ(table.size(), LocalizerOptionTable().size());
  EXPECT_EQ(table[0]["name"], LocalizerOptionTable()[0].name);
  for (const json& row : table) {
    EXPECT_TRUE(row["scope"] == "map" || row["scope"] == "request") << row.dump();
    EXPECT_EQ(row["default"], FindLocalizerOption(row["name"].get<std::string>())->Default());
  }
}

}  // namespace
}  // namespace linecloud
