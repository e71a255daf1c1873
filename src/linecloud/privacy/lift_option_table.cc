#include "linecloud/privacy/lift_option_table.h"

#include "linecloud/io/track_descriptors.h"
#include "linecloud/lifting/sparsify.h"

namespace linecloud {
namespace {

using json = nlohmann::json;
using S = LiftSettings;

OptionField<S> Field(std::string name, OptionType type, std::string help) {
  OptionField<S> f;
  f.name = std::move(name);
  f.type = type;
  f.help = std::move(help);
  return f;
}

OptionField<S> Switch(std::string name, std::string help, std::function<bool&(S&)> member) {
  return MemberField<S, bool>(std::move(name), OptionType::kBool, std::move(help),
                              std::move(member));
}

std::vector<OptionField<S>> MakeTable() {
  std::vector<OptionField<S>> t;
  {
    OptionField<S> f = Field("descriptor", OptionType::kChoice,
                             "How a track's descriptors become one: medoid or mean");
    f.choices = {"medoid", "mean"};
    f.get = [](const S& s) { return json(DescriptorAggregationName(s.options.aggregation)); };
    f.set = [](S& s, const json& v) {
      s.options.aggregation = DescriptorAggregationFromName(v.get<std::string>());
    };
    t.push_back(std::move(f));
  }
  t.push_back(Switch("compact",
                     "The paper's compact encoding (9 bytes per line); a model's first lift with "
                     "it gives the model a key of the 256 compact directions",
                     [](S& s) -> bool& { return s.lifting.compact; }));
  t.push_back(Switch("force",
                     "Replace the output even if another key or other lines lifted it, and lift "
                     "with a key other than the model's (only for files never shared)",
                     [](S& s) -> bool& { return s.options.force; }));
  {
    OptionField<S> f =
        Field("gravity", OptionType::kDirection,
              "The model frame's gravity direction (stored with the map, for the +u methods)");
    f.nullable = true;
    f.null_means = "none: the map has no gravity";
    f.get = [](const S& s) {
      const auto& g = s.options.gravity;
      return g ? json{g->x(), g->y(), g->z()} : json();
    };
    f.set = [](S& s, const json& v) {
      if (v.is_null()) {
        s.options.gravity.reset();
        return;
      }
      Eigen::Vector3d g(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
      // Scaled first: a direction of huge (or tiny) numbers has no finite norm.
      s.options.gravity = (g / g.cwiseAbs().maxCoeff()).normalized();
    };
    t.push_back(std::move(f));
  }
  {
    OptionField<S> f = MemberField<S, double>(
        "sparsify", OptionType::kNumber,
        "Drop this share of the points (keyed, reproducible; the kept points get the same lines "
        "as in the full map)",
        [](S& s) -> double& { return s.lifting.sparsify; });
    f.min = 0;
    f.max = 1;
    f.max_open = true;
    t.push_back(std::move(f));
  }
  {
    OptionField<S> f = Field("sparsify_mode", OptionType::kChoice,
                             "uniform (each point alike) or balanced (cap the local density: at "
                             "most one point per cell of a keyed grid)");
    f.choices = {"uniform", "balanced"};
    f.get = [](const S& s) { return json(std::string(SparsifyModeName(s.lifting.sparsify_mode))); };
    f.set = [](S& s, const json& v) {
      s.lifting.sparsify_mode = SparsifyModeFromName(v.get<std::string>(), "sparsify_mode");
    };
    t.push_back(std::move(f));
  }
  {
    OptionField<S> f = Field("resist_attack", OptionType::kNumber,
                             "Attack-aware sparsification: drop the points the density attack "
                             "recovers (within 1 % of the diagonal), re-attack, until at most "
                             "this share is recovered");
    f.min = 0;
    f.max = 0.99;
    f.nullable = true;
    f.null_means = "off";
    f.get = [](const S& s) {
      return s.lifting.resist_attack < 0 ? json() : json(s.lifting.resist_attack);
    };
    f.set = [](S& s, const json& v) {
      s.lifting.resist_attack = v.is_null() ? -1 : v.get<double>();
    };
    t.push_back(std::move(f));
  }
  {
    OptionField<S> f = MemberField<S, double>(
        "same_place", OptionType::kNumber,
        "Points closer than this share of the scene diagonal count as one place: they get "
        "parallel lines within this map, and a point this close to a line released before "
        "takes that line (up to 3x as far when its descriptor matches the line's)",
        [](S& s) -> double& { return s.options.identity.same_place; });
    f.min = 0;
    f.max = 0.1;
    f.min_open = f.max_open = true;
    t.push_back(std::move(f));
  }
  t.push_back(Switch("allow_shared_key", "Accept a key file that other users can read",
                     [](S& s) -> bool& { return s.options.allow_shared_key; }));
  return t;
}

}  // namespace

const std::vector<OptionField<LiftSettings>>& LiftOptionTable() {
  static const std::vector<OptionField<LiftSettings>> table = MakeTable();
  return table;
}

}  // namespace linecloud
