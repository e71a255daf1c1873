#include "linecloud/io/json_util.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <unordered_set>

#include <fmt/ranges.h>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

std::vector<double> Numbers(const nlohmann::json& j, size_t n, const std::string& where) {
  if (!j.is_array() || j.size() != n) {
    Fail("{}: expected an array of {} numbers", where, n);
  }
  std::vector<double> v(n);
  for (size_t i = 0; i < n; ++i) {
    if (!j[i].is_number()) Fail("{}: element {} is not a number", where, i);
    v[i] = j[i].get<double>();
    if (!std::isfinite(v[i])) Fail("{}: element {} is not finite", where, i);
  }
  return v;
}

}  // namespace

std::string ShownInMessage(const nlohmann::json& value) {
  std::string text = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (text.size() > 80) text = text.substr(0, 77) + "...";
  return text;
}

nlohmann::json ParseJsonUniqueKeys(std::string_view text, const std::string& where) {
  using Event = nlohmann::json::parse_event_t;
  // The keys seen in each open object, hashed: 100 000 keys in one object took 23 s of scanning.
  std::vector<std::unordered_set<std::string>> open_objects;
  std::optional<std::string> twice;
  const nlohmann::json::parser_callback_t seen = [&](int, Event event, nlohmann::json& parsed) {
    if (event == Event::object_start) {
      open_objects.emplace_back();
    } else if (event == Event::object_end) {
      open_objects.pop_back();
    } else if (event == Event::key && !twice) {
      const std::string& key = parsed.get_ref<const std::string&>();
      if (!open_objects.back().insert(key).second) twice = key;
    }
    return true;
  };
  nlohmann::json j = nlohmann::json::parse(text, seen);
  if (twice) Fail("{}: the key {} appears twice in one object", where, ShownInMessage(*twice));
  return j;
}

nlohmann::json ReadJsonFile(const std::string& path) {
  const std::string text = ReadFileToString(path);
  const auto starts_with = [&](std::string_view magic) { return text.rfind(magic, 0) == 0; };
  if (starts_with("\xFF\xD8\xFF") || starts_with("\x89PNG") || starts_with("GIF8") ||
      starts_with("II*") || starts_with("MM\x00*") || starts_with("BM")) {
    Fail(
        "{}: this is an image, not a JSON file (localize --query takes a QUERY.json of "
        "correspondences; see the README for the format)",
        path);
  }
  try {
    return ParseJsonUniqueKeys(text, path);
  } catch (const nlohmann::json::parse_error& e) {
    Fail("{}: invalid JSON at byte {}", path, e.byte);
  } catch (const nlohmann::json::exception& e) {
    // e.g. a number that overflows a double (1e400)
    Fail("{}: invalid JSON ({})", path, e.what());
  }
}

Eigen::Vector3d JsonVector3(const nlohmann::json& j, const std::string& where) {
  const std::vector<double> v = Numbers(j, 3, where);
  return {v[0], v[1], v[2]};
}

std::vector<Eigen::Vector3d> JsonVector3List(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array()) Fail("{}: expected an array of [x, y, z]", where);
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < j.size(); ++i) {
    out.push_back(JsonVector3(j[i], where + "[" + std::to_string(i) + "]"));
  }
  return out;
}

std::vector<PluckerLine> JsonLineList(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array()) Fail("{}: expected an array of [vx, vy, vz, wx, wy, wz]", where);
  std::vector<PluckerLine> out;
  for (size_t i = 0; i < j.size(); ++i) {
    const std::vector<double> v = Numbers(j[i], 6, where + "[" + std::to_string(i) + "]");
    out.emplace_back(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
  }
  return out;
}

void RefuseUnknownFields(const nlohmann::json& object,
                         std::initializer_list<std::string_view> known, std::string_view where) {
  for (const auto& [key, value] : object.items()) {
    if (std::find(known.begin(), known.end(), key) == known.end()) {
      Fail("{}{}unknown field {} ({})", where, where.empty() ? "" : ": ",
           ShownInMessage(nlohmann::json(key)), fmt::join(known, ", "));
    }
  }
}

Rigid3d JsonPose(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) Fail("{}: expected {{\"q\": [w, x, y, z], \"t\": [x, y, z]}}", where);
  // Another field (a "scale", a "center", a misspelling such as "Q") would be ignored: a rigid
  // pose is q and t. Checked first, so that a misspelt field is named rather than "q" missing.
  for (const auto& [key, value] : j.items()) {
    if (key != "q" && key != "t")
      Fail("{}: unknown field {} (a rigid pose has q and t only)", where, ShownInMessage(key));
  }
  for (const char* key : {"q", "t"}) {
    if (!j.contains(key)) {
      Fail("{}.{}: missing (expected {{\"q\": [w, x, y, z], \"t\": [x, y, z]}})", where, key);
    }
  }
  const std::vector<double> q = Numbers(j["q"], 4, where + ".q");
  Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
  if (!(quat.norm() > 1e-9)) Fail("{}.q: zero quaternion", where);
  quat.normalize();
  return Rigid3d(quat, JsonVector3(j["t"], where + ".t"));
}

nlohmann::json PoseToJson(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  return {{"q", {q.w(), q.x(), q.y(), q.z()}}, {"t", {t.x(), t.y(), t.z()}}};
}

JsonFields::JsonFields(const nlohmann::json& j, std::string where)
    : j_(j), where_(std::move(where)) {
  if (!j_.is_object()) Fail("{}: not an object", where_);
}

const nlohmann::json& JsonFields::At(const char* key) const {
  if (!j_.contains(key)) Fail("{}: missing", Where(key));
  return j_[key];
}

double JsonFields::Number(const char* key) const {
  const nlohmann::json& v = At(key);
  if (!v.is_number()) Fail("{}: {} is not a number", Where(key), ShownInMessage(v));
  return v.get<double>();
}

double JsonFields::NumberOrNull(const char* key, double if_null) const {
  return At(key).is_null() ? if_null : Number(key);
}

std::optional<double> JsonFields::Optional(const char* key, double if_null) const {
  if (!Has(key)) return std::nullopt;
  return NumberOrNull(key, if_null);
}

int JsonFields::Int(const char* key) const {
  const nlohmann::json& v = At(key);
  if (!v.is_number_integer() || v.get<int64_t>() != static_cast<int64_t>(v.get<int>()))
    Fail("{}: {} is not an integer", Where(key), ShownInMessage(v));
  return v.get<int>();
}

size_t JsonFields::Count(const char* key) const {
  const nlohmann::json& v = At(key);
  if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0)) {
    Fail("{}: {} is not a count (an integer >= 0)", Where(key), ShownInMessage(v));
  }
  return static_cast<size_t>(v.get<uint64_t>());
}

double JsonFields::Share(const char* key) const {
  const double v = Number(key);
  if (!(v >= 0 && v <= 1)) Fail("{}: {} is not a share in [0, 1]", Where(key), v);
  return v;
}

double JsonFields::NonNegative(const char* key) const {
  const double v = Number(key);
  if (!(v >= 0) || !std::isfinite(v)) Fail("{}: {} is not a finite number >= 0", Where(key), v);
  return v;
}

bool JsonFields::Bool(const char* key) const {
  const nlohmann::json& v = At(key);
  if (!v.is_boolean()) Fail("{}: {} is not true or false", Where(key), ShownInMessage(v));
  return v.get<bool>();
}

std::string JsonFields::String(const char* key) const {
  const nlohmann::json& v = At(key);
  if (!v.is_string()) Fail("{}: {} is not a string", Where(key), ShownInMessage(v));
  return v.get<std::string>();
}

std::string JsonFields::StringOr(const char* key, const std::string& otherwise) const {
  return Has(key) ? String(key) : otherwise;
}

JsonFields JsonFields::Object(const char* key) const { return JsonFields(At(key), Where(key)); }

const nlohmann::json& JsonFields::Array(const char* key) const {
  const nlohmann::json& v = At(key);
  if (!v.is_array()) Fail("{}: not an array", Where(key));
  return v;
}

std::vector<double> JsonFields::Numbers(const char* key) const {
  std::vector<double> out;
  const nlohmann::json& a = Array(key);
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].is_null()) {
      out.push_back(std::numeric_limits<double>::quiet_NaN());
    } else if (a[i].is_number()) {
      out.push_back(a[i].get<double>());
    } else {
      Fail("{}[{}]: {} is not a number", Where(key), i, ShownInMessage(a[i]));
    }
  }
  return out;
}

std::vector<std::string> JsonFields::Strings(const char* key) const {
  std::vector<std::string> out;
  const nlohmann::json& a = Array(key);
  for (size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_string()) Fail("{}[{}]: {} is not a string", Where(key), i, ShownInMessage(a[i]));
    out.push_back(a[i].get<std::string>());
  }
  return out;
}

}  // namespace linecloud
