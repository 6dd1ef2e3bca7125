#pragma once
// The Grafana dashboard shipped in packaging/grafana/linerwatch.json against what the programs
// export: every panel's PromQL parses (Prometheus' own parser, through `promtool check rules`) and
// every linerwatch metric it names is a family of a real scrape. A renamed metric or a typo in a
// panel fails here instead of drawing an empty graph on a site.
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "support/promtool.hpp"

namespace lw::test {

struct GrafanaDashboard {
  std::vector<std::string> panel_exprs;     ///< every target's expr (PromQL)
  std::vector<std::string> variable_exprs;  ///< the template variables' queries (label_values(...): not PromQL)
};

namespace grafana_detail {
inline void CollectPanels(const nlohmann::json& panels, GrafanaDashboard* out) {
  for (const auto& p : panels) {
    if (p.contains("targets"))
      for (const auto& t : p["targets"])
        if (t.contains("expr")) out->panel_exprs.push_back(t["expr"].get<std::string>());
    if (p.contains("panels")) CollectPanels(p["panels"], out);  // a collapsed row holds its panels
  }
}
}  // namespace grafana_detail

/// The dashboard's expressions; throws (nlohmann's parse error, or std::runtime_error) when the
/// file is missing, not JSON, or has no panel with an expression.
inline GrafanaDashboard ReadGrafanaDashboard(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  const nlohmann::json doc = nlohmann::json::parse(in);
  GrafanaDashboard out;
  grafana_detail::CollectPanels(doc.at("panels"), &out);
  if (doc.contains("templating"))
    for (const auto& v : doc["templating"]["list"])
      if (v.contains("definition")) out.variable_exprs.push_back(v["definition"].get<std::string>());
  if (out.panel_exprs.empty()) throw std::runtime_error(path + ": no panel has an expression");
  return out;
}

/// "" when Prometheus parses every expression (each written as a recording rule and checked with
/// `promtool check rules`); otherwise what promtool said, or why it could not run.
inline std::string PromqlCheck(const std::vector<std::string>& exprs) {
  std::ostringstream rules;
  rules << "groups:\n- name: dashboard\n  rules:\n";
  for (size_t i = 0; i < exprs.size(); ++i) {
    std::string quoted;  // a YAML single-quoted scalar: ' doubled
    for (char ch : exprs[i]) quoted += ch == '\'' ? std::string("''") : std::string(1, ch);
    rules << "  - record: dashboard:expr_" << i << "\n    expr: '" << quoted << "'\n";
  }
  return RunPromtool("check rules ", rules.str(), ".yml");
}

/// The linerwatch metric families the expressions name (a histogram's _bucket/_sum/_count series
/// name their family), keeping those for which `keep(name)` is true.
template <typename Keep>
std::set<std::string> MetricFamilies(const std::vector<std::string>& exprs, Keep keep) {
  static const std::regex kName("linerwatch_[a-z0-9_]+");
  std::set<std::string> out;
  for (const auto& e : exprs) {
    for (auto it = std::sregex_iterator(e.begin(), e.end(), kName); it != std::sregex_iterator(); ++it) {
      std::string name = it->str();
      for (const char* suffix : {"_bucket", "_sum", "_count"}) {
        const std::string s = suffix;
        if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) name.resize(name.size() - s.size());
      }
      if (keep(name)) out.insert(name);
    }
  }
  return out;
}

/// The families among `names` that `scrape` (Prometheus text) does not declare with "# TYPE".
inline std::vector<std::string> MissingFamilies(const std::set<std::string>& names, const std::string& scrape) {
  std::vector<std::string> missing;
  for (const auto& n : names)
    if (scrape.find("# TYPE " + n + " ") == std::string::npos) missing.push_back(n);
  return missing;
}

}  // namespace lw::test
