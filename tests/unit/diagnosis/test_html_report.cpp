// The HTML report of a diagnosis (docs/diagnosis.md, "Reading the report"), written from synthetic
// bundles of the test forward model: residual maps before/after over the unwrapped liner, the
// thinnest point with its band, parameter tables with names and units, ranked hypotheses, and
// escaping of whatever the bundle names things.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/bundle.hpp"
#include "diagnosis/diagnose.hpp"
#include "support/temp_directory.hpp"
#include "unit/diagnosis/synthetic_bundle.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

namespace {

struct Run {
  lw::core::Bundle bundle;
  lw::diagnosis::DiagnosisResult result;
  std::string html;
};

Run Diagnose(const lw::test::SyntheticSpec& spec) {
  const lw::test::TempDirectory tmp("lw-report");
  const auto& dir = tmp.path();
  lw::test::WriteSyntheticBundle(dir, spec);
  Run run;
  run.bundle = lw::core::LoadBundle(dir);
  lw::diagnosis::DiagnoseOptions options;
  options.try_pairs = false;
  run.result = lw::diagnosis::Diagnose(run.bundle, options);
  // Through the file writer, as `linerwatch diagnose --html` does.
  const auto path = dir / "report.html";
  lw::diagnosis::WriteHtml(path, run.result);
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  run.html = text.str();
  return run;
}

size_t Count(const std::string& text, const std::string& what, size_t from = 0, size_t to = std::string::npos) {
  size_t n = 0;
  const size_t end = std::min(to, text.size());
  for (size_t p = text.find(what, from); p != std::string::npos && p < end; p = text.find(what, p + 1)) ++n;
  return n;
}

double Rms(const std::vector<double>& a, const std::vector<double>& b) {
  double sq = 0;
  size_t n = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i)
    if (std::isfinite(a[i]) && std::isfinite(b[i])) {
      sq += (a[i] - b[i]) * (a[i] - b[i]);
      ++n;
    }
  return n ? std::sqrt(sq / static_cast<double>(n)) : std::nan("");
}

// The svg element that follows `title` in the document.
std::string SvgAfter(const std::string& html, const std::string& title) {
  const size_t t = html.find(title);
  if (t == std::string::npos) return "";
  const size_t start = html.rfind("<svg", t), end = html.find("</svg>", t);
  return html.substr(start, end - start);
}

}  // namespace

TEST_GROUP(HtmlReport){};

TEST(HtmlReport, ScanCampaignShowsResidualMapsBeforeAndAfterPerFace) {
  lw::test::SyntheticSpec spec;
  spec.seed = 3;
  spec.hardening_h = 0.5;
  spec.hardening_tau_days = 6;
  spec.scan_day = 60;
  const Run run = Diagnose(spec);
  const auto& liner = run.result.liner;
  const size_t faces = run.bundle.map.face_count();

  // One tile per face; one snapshot for the scan, with per-face measured and predicted wear.
  CHECK_TRUE(liner.tiles_are_faces);
  LONGS_EQUAL(faces, liner.tiles.size());
  LONGS_EQUAL(1, liner.snapshots.size());
  const auto& snap = liner.snapshots[0];
  STRCMP_CONTAINS("scan:", snap.source.c_str());
  LONGS_EQUAL(faces, snap.measured_mm.size());
  // The model with the found hardening fits the scan better than plain Eq. 9 face by face.
  const double before = Rms(snap.measured_mm, snap.baseline_mm), after = Rms(snap.measured_mm, snap.improved_mm);
  CHECK_TRUE(std::isfinite(before));
  CHECK_TRUE(after < before);
  char rms[128];
  std::snprintf(rms, sizeof rms, "before %.2f mm, after %.2f mm", before, after);
  STRCMP_CONTAINS(rms, run.html.c_str());

  // Both maps are drawn, every face of each, side by side with the same (mm) scale.
  const std::string b = SvgAfter(run.html, "BEFORE: baseline (plain Eq. 9)");
  const std::string a = SvgAfter(run.html, "AFTER: improved model (findings)");
  CHECK_FALSE(b.empty());
  CHECK_FALSE(a.empty());
  CHECK_TRUE(Count(b, "<polygon") >= faces);
  CHECK_TRUE(Count(a, "<polygon") >= faces);
  STRCMP_CONTAINS("measured minus predicted wear", run.html.c_str());
  STRCMP_CONTAINS("measured - predicted wear (mm)", run.html.c_str());
  // Sensors are marked with their ids on both maps.
  for (const auto& s : run.bundle.crusher.sensors) {
    STRCMP_CONTAINS((">" + s.id + "</text>").c_str(), b.c_str());
    STRCMP_CONTAINS((">" + s.id + "</text>").c_str(), a.c_str());
  }
  // Self-contained: no script, no external resource.
  LONGS_EQUAL(0, Count(run.html, "<script"));
  LONGS_EQUAL(0, Count(run.html, "src="));
  LONGS_EQUAL(0, Count(run.html, "href='http"));
}

TEST(HtmlReport, ThinnestPointWithBandAndParametersWithUnits) {
  lw::test::SyntheticSpec spec;
  spec.seed = 4;
  spec.hardening_h = 0.5;
  spec.hardening_tau_days = 6;
  const Run run = Diagnose(spec);
  const auto& liner = run.result.liner;

  // The live reconstruction's thinnest point first, inside its band, on the liner, in a row.
  CHECK_TRUE(liner.thinnest.size() >= 3);
  const auto& p = liner.thinnest[0];
  CHECK_TRUE(p.lo_mm <= p.thickness_mm && p.thickness_mm <= p.hi_mm);
  // The scan (day 90) corrects the live map, as on the dashboard: this campaign's scan has the
  // discharge edge worn through (up to 106 mm of wear on a 100 mm liner), so 0 is right here.
  CHECK_TRUE(p.thickness_mm >= 0 && p.thickness_mm < run.bundle.crusher.thickness_new_mm);
  STRCMP_CONTAINS("corrected by scan", p.label.c_str());
  CHECK_TRUE(p.z_m >= run.bundle.map.z.minCoeff() - 1e-9 && p.z_m <= run.bundle.map.z.maxCoeff() + 1e-9);
  CHECK_FALSE(p.row.empty());
  char band[96];
  std::snprintf(band, sizeof band, "%.1f .. %.1f", p.lo_mm, p.hi_mm);
  STRCMP_CONTAINS(band, run.html.c_str());
  char value[32];
  std::snprintf(value, sizeof value, "<b>%.1f</b>", p.thickness_mm);
  STRCMP_CONTAINS(value, run.html.c_str());
  STRCMP_CONTAINS(("row " + p.row).c_str(), run.html.c_str());
  LONGS_EQUAL(1, Count(run.html, ">thinnest "));
  LONGS_EQUAL(run.bundle.crusher.rows.size(), liner.reline.size());

  // The work-hardening finding's parameters as a table: names, values, units, uncertainties.
  const auto& f = run.result.findings.at(0);
  STRCMP_EQUAL("work_hardening", f.effect.c_str());
  STRCMP_CONTAINS("<th>parameter</th><th>value</th><th>unit</th><th>uncertainty (1 sd)</th><th>meaning</th>", run.html.c_str());
  char tau[160];
  std::snprintf(tau, sizeof tau, "<code>tau_days</code></td><td class='num'>%.*f</td><td>days</td><td class='num'>&plusmn; ",
                f.parameters["tau_days"].get<double>() >= 10 ? 1 : 2, f.parameters["tau_days"].get<double>());
  STRCMP_CONTAINS(tau, run.html.c_str());
  STRCMP_CONTAINS("<code>h</code></td><td class='num'>", run.html.c_str());
  STRCMP_CONTAINS("<td>fraction</td>", run.html.c_str());
  // Raw JSON no longer stands in for the parameters; *_stderr keys fold into the uncertainty column.
  LONGS_EQUAL(0, Count(run.html, "{&quot;"));
  LONGS_EQUAL(0, Count(run.html, "<code>h_stderr</code>"));

  // Hypotheses ranked by delta BIC, in physical units (tau in days, not log_tau).
  const size_t table = run.html.find("Hypotheses tried, ranked");
  CHECK_TRUE(table != std::string::npos);
  STRCMP_CONTAINS("accepted, chosen", run.html.c_str());
  CHECK_TRUE(Count(run.html, "&tau; = ", table) >= 1);
  LONGS_EQUAL(0, Count(run.html, "log_tau", table));
}

TEST(HtmlReport, WithoutScanSensorResidualsAreDrawnOnPredictedWear) {
  lw::test::SyntheticSpec spec;
  spec.seed = 5;
  spec.with_scan = false;
  spec.hardening_h = 0.5;
  const Run run = Diagnose(spec);
  const auto& liner = run.result.liner;
  LONGS_EQUAL(1, liner.snapshots.size());
  STRCMP_EQUAL("sensors", liner.snapshots[0].source.c_str());
  CHECK_TRUE(liner.snapshots[0].measured_mm.empty());
  LONGS_EQUAL(run.bundle.map.face_count(), liner.snapshots[0].baseline_mm.size());
  STRCMP_CONTAINS("residuals are known <b>only at the sensors</b>", run.html.c_str());
  const std::string b = SvgAfter(run.html, "BEFORE: baseline (plain Eq. 9), predicted wear");
  CHECK_FALSE(b.empty());
  // Each sensor labelled with its residual ("ID: +1.2").
  for (const auto& s : run.bundle.crusher.sensors) STRCMP_CONTAINS((">" + s.id + ": ").c_str(), b.c_str());
}

TEST(HtmlReport, NamesFromTheBundleAreEscaped) {
  lw::test::SyntheticSpec spec;
  spec.seed = 6;
  spec.with_scan = false;
  Run run = Diagnose(spec);
  auto& r = run.result;
  const std::string evil = "<img src=x onerror='alert(1)'>&\"";
  r.crusher_id = evil;
  r.curves.at(0).sensor_id = evil;
  r.curves.at(0).row = evil;
  r.notes.push_back(evil);
  r.data_quality.push_back({evil, "stuck", r.installed_at, r.installed_at, evil});
  lw::diagnosis::Region region;
  region.source = "sensor:" + evil;
  region.sign = evil;
  r.regions.push_back(region);
  const std::string html = lw::diagnosis::RenderHtml(r);
  LONGS_EQUAL(0, Count(html, "<img"));
  LONGS_EQUAL(0, Count(html, "onerror='"));
  CHECK_TRUE(Count(html, "&lt;img src=x onerror=&#39;alert(1)&#39;&gt;&amp;&quot;") >= 6);
}
