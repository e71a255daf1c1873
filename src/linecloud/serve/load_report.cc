#include "linecloud/serve/load_report.h"

#include <fmt/format.h>

namespace linecloud {
namespace {

using json = nlohmann::json;

json StatusesJson(const std::map<int, int>& statuses) {
  json j = json::object();
  for (const auto& [status, n] : statuses) j[std::to_string(status)] = n;
  return j;
}

json ToJson(const LoadLevel& l) {
  return {{"body", l.body},
          {"concurrency", l.concurrency},
          {"requests", l.requests},
          {"per_second", l.per_second},
          {"p50_ms", l.p50_ms},
          {"p99_ms", l.p99_ms},
          {"statuses", StatusesJson(l.statuses)},
          {"poses", l.poses}};
}

json HostileStatusesJson(const AttackSoak& a) {
  json kinds = json::object();
  for (const auto& [kind, statuses] : a.hostile_statuses) kinds[kind] = StatusesJson(statuses);
  return kinds;
}

json ToJson(const AttackSoak& a) {
  return {{"seconds", a.seconds},
          {"attackers", a.attackers},
          {"dribblers", a.dribblers},
          {"alone", ToJson(a.alone)},
          {"under_attack", ToJson(a.under_attack)},
          {"p99_ratio", a.p99_ratio},
          {"hostile_requests", a.hostile_requests},
          {"hostile_statuses", HostileStatusesJson(a)},
          {"rss_before_mb", a.rss_before_mb},
          {"rss_after_mb", a.rss_after_mb}};
}

std::string AttackMarkdown(const AttackSoak& a) {
  std::string md = fmt::format(
      "\nOne client's feature requests, {:.0f} s alone, then {:.0f} s while {} threads send "
      "hostile requests ({} sent) and {} sockets dribble headers:\n\n"
      "| | requests | p50 ms | p99 ms | statuses |\n|---|---|---|---|---|\n",
      a.seconds, a.seconds, a.attackers, a.hostile_requests, a.dribblers);
  for (const auto& [phase, l] : {std::pair<const char*, const LoadLevel*>{"alone", &a.alone},
                                 {"under_attack", &a.under_attack}}) {
    md += fmt::format("| {} | {} | {:.1f} | {:.1f} | {} |\n", phase, l->requests, l->p50_ms,
                      l->p99_ms, StatusesJson(l->statuses).dump());
  }
  md += fmt::format(
      "\np99 under attack / alone: {:.2f}; resident memory {:.1f} -> {:.1f} MB; hostile "
      "statuses by kind: {}\n",
      a.p99_ratio, a.rss_before_mb, a.rss_after_mb, HostileStatusesJson(a).dump());
  return md;
}

}  // namespace

json ToJson(const LoadReport& r) {
  json j = {
      {"map", r.map},     {"client_features", r.client_features},   {"workers", r.workers},
      {"queue", r.queue}, {"hardware_threads", r.hardware_threads}, {"levels", json::array()}};
  if (r.rig_frames) j["rig_frames"] = *r.rig_frames;
  for (const LoadLevel& l : r.levels) j["levels"].push_back(ToJson(l));
  if (r.leak_check) {
    j["leak_check"] = {{"requests", r.leak_check->requests},
                       {"rss_before_mb", r.leak_check->rss_before_mb},
                       {"rss_after_mb", r.leak_check->rss_after_mb},
                       {"statuses", StatusesJson(r.leak_check->statuses)}};
  }
  if (r.attack) j["attack"] = ToJson(*r.attack);
  return j;
}

std::string LoadMarkdown(const LoadReport& r) {
  std::string md = fmt::format(
      "bench serve: map {}, {} client features a request, {} workers, queue {}, {} hardware "
      "threads; client and server on 127.0.0.1\n\n| body | concurrency | requests | req/s | p50 ms "
      "| p99 ms | statuses | poses |\n"
      "|---|---|---|---|---|---|---|---|\n",
      r.map, r.client_features, r.workers, r.queue, r.hardware_threads);
  for (const LoadLevel& l : r.levels) {
    md += fmt::format("| {} | {} | {} | {:.1f} | {:.0f} | {:.0f} | {} | {} |\n", l.body,
                      l.concurrency, l.requests, l.per_second, l.p50_ms, l.p99_ms,
                      StatusesJson(l.statuses).dump(), l.poses);
  }
  if (r.leak_check) {
    md += fmt::format(
        "\n{} more feature requests: resident memory {:.1f} MB before, {:.1f} MB "
        "after; statuses {}\n",
        r.leak_check->requests, r.leak_check->rss_before_mb, r.leak_check->rss_after_mb,
        StatusesJson(r.leak_check->statuses).dump());
  }
  if (r.attack) md += AttackMarkdown(*r.attack);
  return md;
}

}  // namespace linecloud
