// The HTML report of a diagnosis (docs/diagnosis.md, "Reading the report"), written from synthetic
// bundles of the test forward model: residual maps before/after over the unwrapped liner, the
// thinnest point with its band, parameter tables with names and units, ranked hypotheses, and
// escaping of whatever the bundle names things.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
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

Run Diagnose(const lw::test::SyntheticSpec& spec, const std::function<void(lw::core::Bundle&)>& edit = {}) {
  const lw::test::TempDirectory tmp("lw-report");
  const auto& dir = tmp.path();
  lw::test::WriteSyntheticBundle(dir, spec);
  Run run;
  run.bundle = lw::core::LoadBundle(dir);
  if (edit) edit(run.bundle);
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
  // The number to act on is the thinnest area the data support (the dashboard's headline), in the
  // summary and the section; the single face is named as what it is.
  CHECK_FALSE(liner.thinnest_area.empty());
  STRCMP_CONTAINS("thinnest area", liner.thinnest_area.c_str());
  std::string escaped;  // as the report writes text: an apostrophe ("row R's scale") as &#39;
  for (const char ch : liner.thinnest_area) escaped += ch == '\'' ? std::string("&#39;") : std::string(1, ch);
  LONGS_EQUAL(2, Count(run.html, escaped));
  STRCMP_CONTAINS("Thinnest single face of the live map", run.html.c_str());
  CHECK_EQUAL(0, Count(run.html, "The first line is the number to act on"));
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

// The text between `from` and the next `to` (empty when `from` is missing).
std::string Between(const std::string& text, const std::string& from, const std::string& to) {
  const size_t a = text.find(from);
  if (a == std::string::npos) return "";
  const size_t b = text.find(to, a + from.size());
  return text.substr(a, b == std::string::npos ? std::string::npos : b - a);
}

// As the report writes text (an apostrophe as &#39;).
std::string Escaped(const std::string& text) {
  std::string out;
  for (const char ch : text) out += ch == '\'' ? std::string("&#39;") : std::string(1, ch);
  return out;
}

std::string Fixed(double v, int digits) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// "No mismatch" names the noise at the sensors where the residuals are: the largest residual's
// sensor, its size, the noise model's sd there and where that noise comes from; the "after" of a
// campaign without findings says it is a refit, not an improvement; every rejected hypothesis says
// which test it failed and by how much.
TEST(HtmlReport, NoMismatchNamesTheNoiseWhereTheResidualIsAndTheAfterIsARefit) {
  lw::test::SyntheticSpec spec;
  spec.seed = 7;
  spec.with_scan = false;
  const Run run = Diagnose(spec);
  const auto& r = run.result;
  CHECK_TRUE(r.findings.empty());
  STRCMP_EQUAL("refit_baseline", lw::diagnosis::ImprovedModelName(r.improved_model));
  // Every configured sensor is listed, each used one with its residual and the noise allowed there.
  LONGS_EQUAL(run.bundle.crusher.sensors.size(), r.sensors.size());
  const lw::diagnosis::SensorNoise* largest = nullptr;
  for (const auto& n : r.sensors) {
    CHECK_TRUE(n.used);
    CHECK_TRUE(std::isfinite(n.residual_mm));
    CHECK_TRUE(n.noise_sd_mm > 0);
    // The parts add up (root sum of squares) to the total.
    const double sum = n.map_pattern_mm * n.map_pattern_mm + n.map_sampling_mm * n.map_sampling_mm +
                       n.sensor_floor_mm * n.sensor_floor_mm + n.reading_mm * n.reading_mm;
    DOUBLES_EQUAL(n.noise_sd_mm, std::sqrt(sum), 1e-6 * n.noise_sd_mm);
    CHECK_FALSE(n.noise_source.empty());
    CHECK_FALSE(n.noise_detail.empty());
    if (!largest || std::fabs(n.residual_mm) > std::fabs(largest->residual_mm)) largest = &n;
  }
  CHECK_TRUE(largest != nullptr);
  // The verdict at the top says what was tested; below it, the largest residual's sensor, its
  // size, the noise the test allowed there and its source, and the map's own standard error there
  // and why.
  const std::string verdict = Between(run.html, "<div class='summary'>", "</p>");
  CHECK_FALSE(verdict.empty());
  const lw::diagnosis::Verdict v = lw::diagnosis::DescribeVerdict(r);
  STRCMP_CONTAINS(("data-verdict='" + v.kind + "'>" + v.headline + "</b>").c_str(), verdict.c_str());
  // This null campaign's modelled noise is far wider than its scatter; the test learns the noise
  // from the residuals (noise.mismatch_calibration), so it is tested and agrees within it.
  CHECK_TRUE(r.noise_fit.fits);
  STRCMP_EQUAL("no_mismatch", v.kind.c_str());
  CHECK_TRUE(r.noise.at("mismatch_z_modelled_noise").get<double>() < -2);
  CHECK_TRUE(std::fabs(r.mismatch_z_score) <= 2);
  const std::string summary = Between(run.html, "<div class='summary'>", "</div>");
  CHECK_FALSE(largest->explanation.empty());
  STRCMP_CONTAINS(("<li>" + Escaped(largest->explanation) + ".</li>").c_str(), summary.c_str());
  STRCMP_CONTAINS(("sensor " + largest->sensor_id + " is off by " + (largest->residual_mm > 0 ? "+" : "") +
                   Fixed(largest->residual_mm, 1) + " mm")
                      .c_str(),
                  largest->explanation.c_str());
  STRCMP_CONTAINS(("the mismatch test allows " + Fixed(largest->noise_sd_mm, 1) + " mm").c_str(), largest->explanation.c_str());
  STRCMP_CONTAINS(
      ("the map's own standard error at sensor " + largest->sensor_id + " is " + Fixed(largest->map_sd_mm, 1) + " mm").c_str(),
      largest->explanation.c_str());
  // ... and the per-sensor table has every sensor.
  const std::string table = Between(run.html, "id='sensor-noise'", "</table>");
  for (const auto& s : run.bundle.crusher.sensors)
    STRCMP_CONTAINS(("<tr><td>" + s.id + "</td><td>yes</td>").c_str(), table.c_str());
  // "After" is a refit: said so at the top, under the error table and over the right-hand map; no
  // "with the findings" anywhere.
  const std::string glance = Between(run.html, "<div class='summary'>", "</div>");
  STRCMP_CONTAINS("there is no improved model", glance.c_str());
  STRCMP_CONTAINS("a refit, not a finding", glance.c_str());
  STRCMP_CONTAINS("a refit, not a finding", Between(run.html, "id='error'", "<h2").c_str());
  STRCMP_CONTAINS("AFTER: refit only (no findings", run.html.c_str());
  STRCMP_CONTAINS("a refit only, no findings", run.html.c_str());
  LONGS_EQUAL(0, Count(run.html, "with the findings"));
  // Every rejected hypothesis names a failed test with its value and threshold.
  size_t rejected = 0;
  const std::string hyps = Between(run.html, "id='hypotheses'", "</table>");
  for (const auto& hy : r.hypotheses) {
    if (hy.contains("accepted") && hy["accepted"].is_boolean() && hy["accepted"].get<bool>()) continue;
    ++rejected;
    CHECK_TRUE(hy.contains("rejected_because") && hy["rejected_because"].is_string());
    const std::string why = hy["rejected_because"].get<std::string>();
    CHECK_FALSE(why.empty());
    CHECK_TRUE(hy.contains("failed_tests") && !hy["failed_tests"].empty());
    STRCMP_CONTAINS("(needs ", why.c_str());
    STRCMP_CONTAINS(("<b>rejected</b>: " + why.substr(0, 30)).c_str(), hyps.c_str());
    const double delta_bic = hy["delta_bic"].get<double>();
    if (delta_bic <= 10) STRCMP_CONTAINS(("delta BIC " + Fixed(delta_bic, 1) + " (needs > 10)").c_str(), why.c_str());
  }
  CHECK_TRUE(rejected > 0);
  LONGS_EQUAL(0, Count(hyps, "not convincing"));
  // The JSON says the same.
  const auto j = lw::diagnosis::ToJson(r);
  LONGS_EQUAL(r.sensors.size(), j["sensors"].size());
  CHECK_TRUE(j["excluded_sensors"].empty());
  CHECK_TRUE(j["sensors"][0].contains("noise_sd_mm") && j["sensors"][0].contains("noise_source"));
  STRCMP_CONTAINS("a refit, not a finding", j["improved"]["what"].get<std::string>().c_str());
  CHECK_TRUE(j["noise"].contains("model_fits"));
}

// A sensor the fit could not use says why, in the report and in the JSON.
TEST(HtmlReport, EveryExcludedSensorSaysWhy) {
  lw::test::SyntheticSpec spec;
  spec.seed = 8;
  spec.with_scan = false;
  std::string quiet, silent, fast;
  const Run run = Diagnose(spec, [&](lw::core::Bundle& b) {
    // One sensor keeps only its first two readings (no loop crossing), one never reports, one
    // wears 1.6 times as fast as the map says.
    quiet = b.crusher.sensors.at(1).id;
    silent = b.crusher.sensors.at(2).id;
    fast = b.crusher.sensors.at(5).id;
    std::vector<lw::core::Reading> kept;
    size_t n = 0;
    for (auto x : b.readings) {
      if (x.sensor_id == silent || (x.sensor_id == quiet && n++ >= 2)) continue;
      if (x.sensor_id == fast) x.thickness_mm = std::max(0.0, std::floor(100.0 - 1.6 * (100.0 - x.thickness_mm)));
      kept.push_back(x);
    }
    b.readings = kept;
  });
  const auto& r = run.result;
  size_t excluded = 0;
  for (const auto& n : r.sensors) {
    if (n.used) {
      CHECK_TRUE(n.excluded_because.empty());
      continue;
    }
    ++excluded;
    CHECK_FALSE(n.excluded_because.empty());
    // In the report's sensor table, with its reason.
    STRCMP_CONTAINS(("<tr><td>" + n.sensor_id + "</td><td colspan='9'><b>not used</b>: " + n.excluded_because).c_str(),
                    run.html.c_str());
  }
  LONGS_EQUAL(2, excluded);
  const auto* q = [&]() -> const lw::diagnosis::SensorNoise* {
    for (const auto& n : r.sensors)
      if (n.sensor_id == quiet) return &n;
    return nullptr;
  }();
  CHECK_TRUE(q != nullptr);
  STRCMP_CONTAINS("loop crossing", q->excluded_because.c_str());
  // ... with what its readings show beside what the baseline predicts there.
  STRCMP_CONTAINS("where the baseline (Eq. 9, row scales from the other sensors) predicts", q->excluded_because.c_str());
  for (const auto& n : r.sensors)
    if (n.sensor_id == silent) STRCMP_CONTAINS("never reported", n.excluded_because.c_str());
  // The plot title points at the reason; the summary counts them.
  LONGS_EQUAL(2, Count(run.html, ">not used by the fit: why in the table below</text>"));
  STRCMP_CONTAINS(("2 of " + std::to_string(run.bundle.crusher.sensors.size()) + " sensors not used by the fit").c_str(),
                  run.html.c_str());
  // The fast sensor wore more than predicted: + in the JSON, in the table and on the maps' labels
  // (measured - predicted wear), red.
  for (const auto& n : r.sensors)
    if (n.sensor_id == fast) {
      CHECK_TRUE(n.residual_mm > 5);
      STRCMP_CONTAINS(
          ("<tr><td>" + fast + "</td><td>yes</td><td class='num'>" + Fixed(n.day, 0) + "</td><td class='num'>+").c_str(),
          run.html.c_str());
    }
  const std::string before = SvgAfter(run.html, "BEFORE: baseline (plain Eq. 9), predicted wear");
  STRCMP_CONTAINS((">" + fast + ": +").c_str(), before.c_str());
  const auto j = lw::diagnosis::ToJson(r);
  LONGS_EQUAL(2, j["excluded_sensors"].size());
  for (const auto& x : j["excluded_sensors"]) CHECK_FALSE(x["reason"].get<std::string>().empty());
}

// When the noise model does not fit the data, or the noise is as large as the wear, "no mismatch"
// is not shown as agreement (no green): the verdict says what it means, with what the test could
// have seen.
TEST(HtmlReport, NoMismatchWithANoiseModelThatDoesNotFitIsNotGreen) {
  lw::test::SyntheticSpec spec;
  spec.seed = 7;
  spec.with_scan = false;
  Run run = Diagnose(spec);
  auto& r = run.result;
  CHECK_TRUE(r.findings.empty());
  CHECK_FALSE(r.noise_fit.blind);  // the forward model's map error is small
  CHECK_TRUE(std::isfinite(r.noise_fit.chi2_to_detect));
  // A noise model that fits: green, with what the test could have seen.
  r.noise_fit.fits = true;
  r.noise_fit.detail.clear();
  std::string html = lw::diagnosis::RenderHtml(r);
  STRCMP_CONTAINS("<b class='good' data-verdict='no_mismatch'>No mismatch beyond the noise</b>", html.c_str());
  STRCMP_CONTAINS(("rise by about " + Fixed(r.noise_fit.chi2_to_detect, 0)).c_str(),
                  Between(html, "<div class='summary'>", "</p>").c_str());

  // The noise model does not fit (not blind): never green, and it says nothing was tested.
  r.noise_fit.fits = false;
  r.noise_fit.detail = "chi-square per sensor event 0.004 (1 expected)";
  html = lw::diagnosis::RenderHtml(r);
  std::string verdict = Between(html, "<div class='summary'>", "</p>");
  LONGS_EQUAL(0, Count(verdict, "class='good'"));
  LONGS_EQUAL(0, Count(verdict, "No mismatch"));
  STRCMP_CONTAINS("Not tested: the noise model does not fit these data", verdict.c_str());
  STRCMP_CONTAINS("chi-square per sensor event 0.004", verdict.c_str());
  STRCMP_CONTAINS("no evidence that the DEM-based prediction agrees with the recordings", verdict.c_str());
  STRCMP_CONTAINS(("a static error of about " + Fixed(r.noise_fit.detectable_sd_per_sensor, 1) + " noise sd").c_str(),
                  verdict.c_str());
  STRCMP_CONTAINS("nothing was tested", Between(html, "id='findings'", "<h2").c_str());
  const auto j = lw::diagnosis::ToJson(r);
  STRCMP_EQUAL("noise_model_does_not_fit", j["verdict"]["kind"].get<std::string>().c_str());
  CHECK_TRUE(j["noise"].contains("detection_limit"));

  // The noise as large as the wear (the noise model otherwise fits): not testable.
  r.noise_fit.fits = true;
  r.noise_fit.detail.clear();
  r.noise_fit.blind = true;
  r.noise_fit.blind_detail = "the map's pattern error is 87 % of the predicted wear";
  html = lw::diagnosis::RenderHtml(r);
  verdict = Between(html, "<div class='summary'>", "</p>");
  LONGS_EQUAL(0, Count(verdict, "class='good'"));
  STRCMP_CONTAINS("could not have seen one", verdict.c_str());
  STRCMP_CONTAINS("not testable with this map", verdict.c_str());
  STRCMP_CONTAINS("the map&#39;s pattern error is 87 % of the predicted wear", verdict.c_str());
  STRCMP_CONTAINS("as large as the wear here", Between(html, "id='findings'", "<h2").c_str());
}

TEST(HtmlReport, EveryEffectNotNamedHasADetectionLimitInTheJsonAndTheReport) {
  lw::test::SyntheticSpec spec;
  spec.seed = 7;
  spec.with_scan = false;
  const Run run = Diagnose(spec);
  const auto& r = run.result;
  CHECK_TRUE(r.findings.empty());
  // Every single effect tried has a limit from its fit's standard error: positive, finite, at
  // least the size test's bar of 2 standard errors above zero.
  CHECK_TRUE(r.limits.size() >= 4);
  const nlohmann::ordered_json j = lw::diagnosis::ToJson(r);
  CHECK_TRUE(j.contains("limits"));
  size_t not_named = 0;
  for (const auto& l : r.limits) {
    CHECK_FALSE(l.named);
    CHECK_TRUE(std::isfinite(l.min_detectable) && l.min_detectable > 0);
    CHECK_TRUE(l.min_detectable >= 2.0 * l.stderr_);
    CHECK_TRUE(l.z_needed >= 2.0);
    ++not_named;
    bool in_json = false;
    for (const auto& x : j["limits"])
      if (x["effect"] == l.effect) {
        in_json = true;
        CHECK_TRUE(x["min_detectable"].contains(l.parameter));
        CHECK_TRUE(x["would_show_with"].is_string());
      }
    CHECK_TRUE(in_json);
    CHECK_TRUE(l.sentence.find("would not show by day") != std::string::npos);
    CHECK_TRUE(run.html.find(l.effect == "feed_segregation" ? "feed segregation" : "would not show") != std::string::npos);
    CHECK_TRUE(run.html.find("would not show by day") != std::string::npos);
  }
  LONGS_EQUAL(not_named, j["limits"].size());
  // One limit per effect (profile_evolution's smaller form).
  for (size_t a = 0; a < r.limits.size(); ++a)
    for (size_t b = a + 1; b < r.limits.size(); ++b) CHECK_TRUE(r.limits[a].effect != r.limits[b].effect);
}
