// Self-contained HTML report: inline SVG only, no scripts, no external resources.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "diagnosis/diagnose.hpp"

namespace lw::diagnosis {
namespace {

std::string Esc(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string Num(double v, int digits = 2) {
  if (!std::isfinite(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// Diverging blue (negative) - white - red (positive) colour for v in [-1, 1].
std::string Diverging(double v) {
  v = std::clamp(v, -1.0, 1.0);
  int r, g, b;
  if (v >= 0) {
    r = 255;
    g = static_cast<int>(255 * (1 - v));
    b = static_cast<int>(255 * (1 - v));
  } else {
    r = static_cast<int>(255 * (1 + v));
    g = static_cast<int>(255 * (1 + v));
    b = 255;
  }
  char buf[16];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", r, g, b);
  return buf;
}

std::string Sequential(double v) {
  v = std::clamp(v, 0.0, 1.0);
  const int r = static_cast<int>(255 * (1 - 0.8 * v));
  const int g = static_cast<int>(255 * (1 - 0.6 * v));
  const int b = static_cast<int>(255 * (1 - 0.2 * v));
  char buf[16];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", r, g, b);
  return buf;
}

std::string SensorPlot(const SensorCurve& c) {
  const double w = 320, h = 200, ml = 40, mr = 8, mt = 18, mb = 26;
  double tmax = 1, ymin = 1e300, ymax = -1e300;
  for (double t : c.reading_days) tmax = std::max(tmax, t);
  for (double t : c.model_days) tmax = std::max(tmax, t);
  auto span = [&](const std::vector<double>& v) {
    for (double y : v)
      if (std::isfinite(y)) {
        ymin = std::min(ymin, y);
        ymax = std::max(ymax, y);
      }
  };
  span(c.reading_mm);
  span(c.baseline_thickness_mm);
  span(c.improved_thickness_mm);
  if (ymin > ymax) {
    ymin = 0;
    ymax = 1;
  }
  ymax = std::min(ymax, c.thickness_new_mm + 2);
  ymin = std::max(ymin, -2.0);
  if (ymax - ymin < 2) ymax = ymin + 2;
  auto X = [&](double t) { return ml + (w - ml - mr) * t / tmax; };
  auto Y = [&](double y) { return mt + (h - mt - mb) * (ymax - y) / (ymax - ymin); };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h << "' class='plot'>";
  s << "<text x='" << ml << "' y='12' font-size='11'>" << Esc(c.sensor_id) << " (" << Esc(c.row) << ")"
    << (c.used ? "" : " - not used") << "</text>";
  s << "<rect x='" << ml << "' y='" << mt << "' width='" << (w - ml - mr) << "' height='" << (h - mt - mb)
    << "' fill='none' stroke='#999'/>";
  for (int k = 0; k <= 4; ++k) {
    const double y = ymin + (ymax - ymin) * k / 4.0;
    s << "<text x='2' y='" << Y(y) + 3 << "' font-size='9'>" << Num(y, 0) << "</text>";
    const double t = tmax * k / 4.0;
    s << "<text x='" << X(t) - 6 << "' y='" << h - 12 << "' font-size='9'>" << Num(t, 0) << "</text>";
  }
  s << "<text x='" << (w / 2) << "' y='" << h - 2 << "' font-size='9'>days</text>";
  const size_t stride = std::max<size_t>(1, c.reading_days.size() / 400);
  for (size_t i = 0; i < c.reading_days.size(); i += stride) {
    const double y = c.reading_mm[i];
    if (!std::isfinite(y) || y < ymin - 1 || y > ymax + 1) continue;
    s << "<circle cx='" << Num(X(c.reading_days[i]), 1) << "' cy='" << Num(Y(y), 1) << "' r='1.3' fill='"
      << (c.reading_used[i] ? "#333" : "#e33") << "'/>";
  }
  auto line = [&](const std::vector<double>& ys, const char* colour, const char* dash) {
    s << "<polyline fill='none' stroke='" << colour << "' stroke-width='1.5' stroke-dasharray='" << dash
      << "' points='";
    for (size_t i = 0; i < c.model_days.size() && i < ys.size(); ++i)
      s << Num(X(c.model_days[i]), 1) << "," << Num(Y(ys[i]), 1) << " ";
    s << "'/>";
  };
  line(c.baseline_thickness_mm, "#888", "5,3");
  line(c.improved_thickness_mm, "#1565c0", "none");
  s << "</svg>";
  return s.str();
}

std::string GridPlot(const ResidualGrid& g, const std::vector<double>& v, const std::string& title, bool diverging,
                     double scale) {
  const double cw = std::max(4.0, std::min(14.0, 480.0 / std::max<double>(1.0, static_cast<double>(g.ntheta))));
  const double ch = std::max(4.0, std::min(14.0, 240.0 / std::max<double>(1.0, static_cast<double>(g.nz))));
  const double ml = 40, mt = 18;
  const double w = ml + cw * static_cast<double>(g.ntheta) + 10, h = mt + ch * static_cast<double>(g.nz) + 30;
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h << "'>";
  s << "<text x='" << ml << "' y='12' font-size='11'>" << Esc(title) << " (scale +-" << Num(scale, 1)
    << " mm)</text>";
  for (size_t iz = 0; iz < g.nz; ++iz) {
    for (size_t it = 0; it < g.ntheta; ++it) {
      const double x = v[iz * g.ntheta + it];
      if (!std::isfinite(x)) continue;
      const std::string colour = diverging ? Diverging(x / scale) : Sequential(x / scale);
      s << "<rect x='" << Num(ml + cw * static_cast<double>(it), 1) << "' y='"
        << Num(mt + ch * static_cast<double>(g.nz - 1 - iz), 1) << "' width='" << Num(cw, 1) << "' height='"
        << Num(ch, 1) << "' fill='" << colour << "'><title>" << Num(x, 2) << " mm</title></rect>";
    }
  }
  s << "<text x='2' y='" << mt + 8 << "' font-size='9'>z " << Num(g.z_max_m, 2) << "</text>";
  s << "<text x='2' y='" << mt + ch * static_cast<double>(g.nz) << "' font-size='9'>z " << Num(g.z_min_m, 2)
    << "</text>";
  s << "<text x='" << ml << "' y='" << h - 6 << "' font-size='9'>theta " << Num(g.theta_min_deg, 0) << " .. "
    << Num(g.theta_max_deg, 0) << " deg</text>";
  s << "</svg>";
  return s.str();
}

}  // namespace

std::string RenderHtml(const DiagnosisResult& r) {
  std::ostringstream h;
  h << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>linerwatch diagnosis " << Esc(r.crusher_id)
    << "</title><style>body{font-family:sans-serif;margin:20px;max-width:1400px}table{border-collapse:collapse;"
       "margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;font-size:13px;vertical-align:top}"
       ".plots svg{margin:4px;border:1px solid #eee}.good{color:#2e7d32}.bad{color:#c62828}</style></head><body>";
  h << "<h1>Diagnosis: " << Esc(r.crusher_id) << "</h1>";
  h << "<p>Installed " << core::FormatIsoTime(r.installed_at) << ". Mismatch "
    << (r.mismatch_detected ? "<b class='bad'>detected</b>" : "<b class='good'>not detected</b>")
    << " (chi-square excess " << Num(r.mismatch_z_score, 1) << " sigma over the noise model).</p>";

  h << "<h2>Findings</h2>";
  if (r.findings.empty()) {
    h << "<p>No finding: the DEM-based reconstruction agrees with the recordings within the noise.</p>";
  } else {
    h << "<table><tr><th>#</th><th>effect</th><th>confidence</th><th>explanation</th><th>parameters</th></tr>";
    int k = 1;
    for (const Finding& f : r.findings) {
      h << "<tr><td>" << k++ << "</td><td><b>" << Esc(f.effect) << "</b></td><td>" << Num(f.confidence, 2)
        << "</td><td>" << Esc(f.explanation) << "</td><td><code>" << Esc(f.parameters.dump()) << "</code></td></tr>";
    }
    h << "</table>";
  }
  h << "<h2>Error (mm of wear)</h2><table><tr><th></th><th>RMSE</th><th>max |error|</th><th>held-out RMSE</th></tr>";
  h << "<tr><td>baseline (Eq. 9, wear linear in time)</td><td>" << Num(r.baseline.rmse_mm) << "</td><td>"
    << Num(r.baseline.max_abs_mm) << "</td><td>" << Num(r.baseline.holdout_rmse_mm) << "</td></tr>";
  h << "<tr><td>improved (findings modelled)</td><td>" << Num(r.improved.rmse_mm) << "</td><td>"
    << Num(r.improved.max_abs_mm) << "</td><td>" << Num(r.improved.holdout_rmse_mm) << "</td></tr></table>";

  if (!r.regions.empty()) {
    h << "<h2>Mismatch regions</h2><table><tr><th>source</th><th>z (m)</th><th>theta (deg)</th><th>from</th>"
         "<th>to</th><th>sign</th><th>size (mm)</th></tr>";
    for (const Region& g : r.regions) {
      h << "<tr><td>" << Esc(g.source) << "</td><td>" << Num(g.z_min_m, 3) << " .. " << Num(g.z_max_m, 3)
        << "</td><td>" << Num(g.theta_min_deg, 1) << " .. " << Num(g.theta_max_deg, 1) << "</td><td>"
        << core::FormatIsoTime(g.from) << "</td><td>" << core::FormatIsoTime(g.to) << "</td><td>" << g.sign
        << "</td><td>" << Num(g.size_mm) << "</td></tr>";
    }
    h << "</table>";
  }

  for (const ResidualGrid& g : r.grids) {
    double scale = 0.5, mscale = 1;
    for (size_t i = 0; i < g.before_mm.size(); ++i) {
      if (std::isfinite(g.before_mm[i])) scale = std::max(scale, std::fabs(g.before_mm[i]));
      if (std::isfinite(g.measured_mm[i])) mscale = std::max(mscale, g.measured_mm[i]);
    }
    h << "<h2>Scan " << Esc(g.scan_file) << " (" << core::FormatIsoTime(g.date)
      << "): residual over the unwrapped liner</h2><p>Residual = model - measured wear (red: model predicts more "
         "wear than measured, \"over\"; blue: \"under\").</p><div class='plots'>";
    h << GridPlot(g, g.measured_mm, "measured wear", false, mscale);
    h << GridPlot(g, g.before_mm, "residual before (baseline)", true, scale);
    h << GridPlot(g, g.after_mm, "residual after (improved)", true, scale);
    h << "</div>";
  }

  h << "<h2>Sensors: measured vs predicted thickness</h2><p>Dots: readings (red: excluded as faults). Grey "
       "dashed: baseline. Blue: improved model.</p><div class='plots'>";
  for (const SensorCurve& c : r.curves) h << SensorPlot(c);
  h << "</div>";

  h << "<h2>Data quality</h2>";
  if (r.data_quality.empty()) {
    h << "<p>No sensor fault found.</p>";
  } else {
    h << "<table><tr><th>sensor</th><th>issue</th><th>from</th><th>to</th><th>detail</th></tr>";
    for (const DataQualityIssue& d : r.data_quality)
      h << "<tr><td>" << Esc(d.sensor_id) << "</td><td>" << Esc(d.issue) << "</td><td>" << core::FormatIsoTime(d.from)
        << "</td><td>" << core::FormatIsoTime(d.to) << "</td><td>" << Esc(d.detail) << "</td></tr>";
    h << "</table>";
  }
  h << "<h2>Hypotheses tried</h2><table><tr><th>model</th><th>delta BIC</th><th>held-out improvement</th>"
       "<th>accepted</th><th>parameters</th></tr>";
  for (const auto& hy : r.hypotheses) {
    h << "<tr><td>" << Esc(hy.value("model", "")) << "</td><td>" << Num(hy.value("delta_bic", 0.0)) << "</td><td>"
      << Num(100.0 * hy.value("holdout_improvement", 0.0), 1) << " %</td><td>"
      << (hy.value("accepted", false) ? "yes" : "no") << "</td><td><code>"
      << Esc(hy.contains("parameters") ? hy["parameters"].dump() : "") << "</code></td></tr>";
  }
  h << "</table>";
  if (!r.notes.empty()) {
    h << "<h2>Notes</h2><ul>";
    for (const std::string& n : r.notes) h << "<li>" << Esc(n) << "</li>";
    h << "</ul>";
  }
  h << "</body></html>\n";
  return h.str();
}

void WriteHtml(const std::filesystem::path& path, const DiagnosisResult& result) {
  const std::string text = RenderHtml(result);
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw std::runtime_error(path.string() + ": cannot write");
    out << text;
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw std::runtime_error(path.string() + ": write failed");
    }
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace lw::diagnosis
