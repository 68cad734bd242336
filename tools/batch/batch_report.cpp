#include "batch_report.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <string>

#include "app/report_json.h"
#include "hgdeform/version.h"

namespace hgdcli {
namespace batch {

namespace {

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string general(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::vector<ScanResult> sorted(std::vector<ScanResult> v) {
  std::sort(v.begin(), v.end(), [](const ScanResult& a, const ScanResult& b) { return a.file < b.file; });
  return v;
}

}  // namespace

Totals countResults(const std::vector<ScanResult>& results) {
  Totals t;
  t.scans = results.size();
  for (const auto& r : results) {
    if (r.status == "ok") {
      ++t.ok;
      t.points += r.report.points;
    } else if (r.status == "skipped") {
      ++t.skipped;
    } else {
      ++t.failed;
    }
  }
  return t;
}

nlohmann::json toJson(const ScanResult& r) {
  nlohmann::json j;
  j["file"] = r.file;
  j["output"] = r.output;
  j["scenario"] = r.scenario;
  j["own_scenario"] = r.own_scenario;
  j["status"] = r.status;
  j["reason"] = r.reason;
  j["error"] = r.error;
  j["warning"] = r.warning;
  j["notes"] = r.report.notes;
  j["thumbnail"] = r.thumbnail;
  j["rank"] = r.rank;
  j["ms_wall"] = r.ms_wall;
  if (r.has_metrics) {
    j.update(hgd::reportFigures(r.report));  // points, clusters, iterations, frames, handle_error, ms
  } else {
    for (const char* k : {"points", "clusters", "iterations", "frames", "handle_error", "ms"}) j[k] = nullptr;
  }
  return j;
}

ScanResult fromJson(const nlohmann::json& j) {
  ScanResult r;
  r.file = j.at("file").get<std::string>();
  r.output = j.at("output").get<std::string>();
  r.scenario = j.at("scenario").get<std::string>();
  r.own_scenario = j.at("own_scenario").get<bool>();
  r.status = j.at("status").get<std::string>();
  r.reason = j.value("reason", std::string());
  r.error = j.at("error").get<std::string>();
  r.warning = j.value("warning", std::string());
  r.report.notes = j.value("notes", std::vector<std::string>());
  r.thumbnail = j.at("thumbnail").get<std::string>();
  r.rank = j.at("rank").get<int>();
  r.ms_wall = j.at("ms_wall").get<double>();
  r.has_metrics = !j.at("points").is_null();
  if (r.has_metrics) hgd::readReportFigures(j, r.report);
  return r;
}

std::string summaryJson(const std::vector<ScanResult>& results, const Totals& t,
                        const std::vector<std::string>& warnings) {
  nlohmann::json j;
  j["format"] = "hgdeform-batch-summary/1";
  j["tool"] = "hgdeform batch";
  j["version"] = hgd::version();
  j["scans"] = nlohmann::json::array();
  for (const auto& r : sorted(results)) j["scans"].push_back(toJson(r));
  j["totals"] = {{"scans", t.scans},
                 {"ok", t.ok},
                 {"failed", t.failed},
                 {"skipped", t.skipped},
                 {"points", t.points},
                 {"wall_s", t.wall_s},
                 {"files_per_s", t.wall_s > 0 ? static_cast<double>(t.scans) / t.wall_s : 0.0},
                 {"jobs", t.jobs},
                 {"ranks", t.ranks},
                 {"shard", t.shard},
                 {"skipped_entries", t.skipped_entries.size()}};
  j["skipped_entries"] = nlohmann::json::array();
  for (const auto& e : t.skipped_entries) j["skipped_entries"].push_back({{"path", e.path}, {"why", e.why}});
  j["warnings"] = warnings;
  return j.dump(2) + "\n";
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q += '"';
    q += c;
  }
  return q + "\"";
}

std::string summaryCsv(const std::vector<ScanResult>& results) {
  std::string out =
      "file,status,error,points,clusters,iterations,handle_error,ms_build,ms_field,ms_sampling,ms_clusters,"
      "ms_solve,ms_interpolation,ms_total,reason\r\n";
  for (const auto& r : sorted(results)) {
    out += csvField(r.file) + ',' + csvField(r.status) + ',' + csvField(r.error);
    if (r.has_metrics) {
      out += ',' + std::to_string(r.report.points) + ',' + std::to_string(r.report.clusters) + ',' +
             std::to_string(r.report.iterations) + ',' + general(r.report.handle_error);
      for (double ms : {r.report.build_ms, r.report.field_ms, r.report.sampling_ms, r.report.clusters_ms,
                        r.report.solve_ms, r.report.interpolation_ms, r.report.total_ms})
        out += ',' + fixed(ms, 3);
    } else {
      out += ",,,,,,,,,,,";
    }
    out += ',' + csvField(r.reason) + "\r\n";
  }
  return out;
}

std::string htmlEscape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&#39;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string urlPath(const std::string& s) {
  static const char* hex = "0123456789ABCDEF";
  std::string o;
  for (unsigned char c : s) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~' || c == '/') {
      o += static_cast<char>(c);
    } else {
      o += '%';
      o += hex[c >> 4];
      o += hex[c & 15];
    }
  }
  return o;
}

std::string indexHtml(const std::vector<ScanResult>& results, const Totals& t, const std::string& note) {
  std::string h =
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<title>hgdeform batch</title>\n<style>\n"
      "body { font-family: sans-serif; margin: 1.5em; }\n"
      "table { border-collapse: collapse; }\n"
      "td, th { border: 1px solid #ccc; padding: 4px 8px; vertical-align: top; text-align: left; }\n"
      "td.ok { color: #080; } td.failed { color: #b00; font-weight: bold; } td.skipped { color: #666; }\n"
      "img { max-width: 480px; }\n"
      ".note { background: #ffd; border: 1px solid #cc8; padding: 0.5em; }\n"
      "</style>\n</head>\n<body>\n<h1>hgdeform batch</h1>\n";
  h += "<p>" + std::to_string(t.scans) + " scans: " + std::to_string(t.ok) + " ok, " +
       std::to_string(t.failed) + " failed, " + std::to_string(t.skipped) + " skipped (up to date); " +
       fixed(t.wall_s, 1) + " s";
  if (!t.shard.empty()) h += "; shard " + htmlEscape(t.shard);
  if (t.ranks > 1) h += "; " + std::to_string(t.ranks) + " MPI ranks";
  h += ".</p>\n";
  if (!note.empty()) h += "<p class=\"note\">" + htmlEscape(note) + "</p>\n";
  if (!t.skipped_entries.empty()) {
    h += "<p class=\"note\">Not taken as scans:</p>\n<ul>\n";
    for (const auto& e : t.skipped_entries)
      h += "<li>" + htmlEscape(e.path) + ": " + htmlEscape(e.why) + "</li>\n";
    h += "</ul>\n";
  }
  h += "<table>\n<tr><th>#</th><th>file</th><th>status</th><th>points</th><th>clusters</th>"
       "<th>iterations</th><th>ms</th><th>before / after</th></tr>\n";
  int n = 0;
  for (const auto& r : sorted(results)) {
    h += "<tr id=\"" + htmlEscape(urlPath(r.file)) + "\"><td>" + std::to_string(++n) + "</td><td>" +
         htmlEscape(r.file);
    if (r.own_scenario) h += "<br><small>scenario " + htmlEscape(r.scenario) + "</small>";
    h += "</td><td class=\"" + htmlEscape(r.status) + "\">" + htmlEscape(r.status);
    if (!r.reason.empty()) h += "<br><small>" + htmlEscape(r.reason) + "</small>";
    h += "</td>";
    if (r.has_metrics)
      h += "<td>" + std::to_string(r.report.points) + "</td><td>" + std::to_string(r.report.clusters) +
           "</td><td>" + std::to_string(r.report.iterations) + "</td><td>" + fixed(r.report.total_ms, 0) +
           "</td>";
    else
      h += "<td></td><td></td><td></td><td></td>";
    h += "<td>";
    if (!r.error.empty()) h += "<pre>" + htmlEscape(r.error) + "</pre>";
    if (!r.thumbnail.empty())
      h += "<a href=\"" + htmlEscape(urlPath(r.thumbnail)) + "\"><img src=\"" +
           htmlEscape(urlPath(r.thumbnail)) + "\" alt=\"" + htmlEscape(r.file) + " before and after\"></a>";
    h += "</td></tr>\n";
  }
  h += "</table>\n</body>\n</html>\n";
  return h;
}

}  // namespace batch
}  // namespace hgdcli
