// The diagnosis JSON document (docs/diagnosis.md, "Output").
#include <cmath>

#include "diagnosis/diagnose.hpp"

namespace lw::diagnosis {
namespace {

double Round(double v, double digits = 3) {
  if (!std::isfinite(v)) return 0;
  const double f = std::pow(10.0, digits);
  return std::round(v * f) / f;
}

nlohmann::ordered_json Errors(const ErrorSummary& e) {
  nlohmann::ordered_json j;
  j["rmse_mm"] = Round(e.rmse_mm);
  j["max_abs_mm"] = Round(e.max_abs_mm);
  j["holdout_rmse_mm"] = Round(e.holdout_rmse_mm);
  j["observations"] = e.observations;
  j["holdout_observations"] = e.holdout_observations;
  return j;
}

}  // namespace

namespace {
// Per effect not named: the smallest strength these data would have shown (docs/diagnosis.md, *Reading the outputs*, `limits`).
nlohmann::ordered_json LimitsJson(const std::vector<DetectionLimit>& limits) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const DetectionLimit& l : limits) {
    if (l.named) continue;
    nlohmann::ordered_json x;
    x["effect"] = l.effect;
    x["min_detectable"] = {{l.parameter, Round(l.min_detectable, 4)}};
    x["would_show_with"] = l.would_show_with;
    x["form"] = l.form;
    x["stderr"] = Round(l.stderr_, 4);
    x["standard_errors_needed"] = Round(l.z_needed, 2);
    x["until_day"] = Round(l.until_day, 1);
    x["text"] = l.sentence;
    out.push_back(x);
  }
  return out;
}
}  // namespace

nlohmann::ordered_json ToJson(const DiagnosisResult& r) {
  nlohmann::ordered_json j;
  j["crusher_id"] = r.crusher_id;
  j["baseline"] = Errors(r.baseline);
  nlohmann::ordered_json mismatch;
  mismatch["detected"] = r.mismatch_detected;
  mismatch["z_score"] = Round(r.mismatch_z_score, 2);
  mismatch["regions"] = nlohmann::ordered_json::array();
  for (const Region& g : r.regions) {
    nlohmann::ordered_json x;
    x["z_min_m"] = Round(g.z_min_m, 4);
    x["z_max_m"] = Round(g.z_max_m, 4);
    x["theta_min_deg"] = Round(g.theta_min_deg, 2);
    x["theta_max_deg"] = Round(g.theta_max_deg, 2);
    x["from"] = core::FormatIsoTime(g.from);
    x["to"] = core::FormatIsoTime(g.to);
    x["sign"] = g.sign;
    x["size_mm"] = Round(g.size_mm, 2);
    x["source"] = g.source;
    mismatch["regions"].push_back(x);
  }
  j["mismatch"] = mismatch;
  j["findings"] = nlohmann::ordered_json::array();
  for (const Finding& f : r.findings) {
    nlohmann::ordered_json x;
    x["effect"] = f.effect;
    x["confidence"] = Round(f.confidence);
    x["explanation"] = f.explanation;
    x["parameters"] = f.parameters;
    x["evidence"] = f.evidence;
    j["findings"].push_back(x);
  }
  j["improved"] = Errors(r.improved);
  j["improved"]["model"] = ImprovedModelName(r.improved_model);
  j["improved"]["what"] = ImprovedModelDescription(r.improved_model);
  j["limits"] = LimitsJson(r.limits);
  j["data_quality"] = nlohmann::ordered_json::array();
  for (const DataQualityIssue& d : r.data_quality) {
    nlohmann::ordered_json x;
    x["sensor_id"] = d.sensor_id;
    x["issue"] = d.issue;
    x["from"] = core::FormatIsoTime(d.from);
    x["to"] = core::FormatIsoTime(d.to);
    x["detail"] = d.detail;
    j["data_quality"].push_back(x);
  }
  if (r.prediction) {
    nlohmann::ordered_json p;
    p["time"] = core::FormatIsoTime(r.prediction->time);
    nlohmann::ordered_json b = nlohmann::ordered_json::object(), i = nlohmann::ordered_json::object(),
                           f = nlohmann::ordered_json::object();
    for (const SensorPrediction& s : r.prediction->sensors) {
      b[s.sensor_id] = Round(s.baseline_thickness_mm, 3);
      i[s.sensor_id] = Round(s.improved_thickness_mm, 3);
      f[s.sensor_id] = Round(s.refit_thickness_mm, 3);
    }
    p["baseline"]["sensors"] = b;
    p["improved"]["sensors"] = i;
    p["refit_baseline"]["sensors"] = f;
    const Prediction::ScanAnchor& a = r.prediction->faces_scan;
    if (!a.file.empty() || !a.detail.empty()) {
      nlohmann::ordered_json s;
      s["file"] = a.file;
      s["date"] = core::FormatIsoTime(a.date);
      s["applied"] = a.detail.empty();
      s["faces_measured"] = a.faces_measured;
      s["faces_filled"] = a.faces_filled;
      s["sensors_used"] = a.sensors_used;
      if (!a.detail.empty()) s["detail"] = a.detail;
      p["faces_scan"] = s;
    }
    j["prediction"] = p;
  }
  j["noise"] = r.noise;
  j["noise"]["model_fits"] = r.noise_fit.fits;
  if (!r.noise_fit.fits) j["noise"]["model_fit_detail"] = r.noise_fit.detail;
  j["noise"]["mismatch_test_blind"] = r.noise_fit.blind;
  if (r.noise_fit.blind) j["noise"]["mismatch_test_blind_detail"] = r.noise_fit.blind_detail;
  if (std::isfinite(r.noise_fit.chi2_to_detect))
    j["noise"]["detection_limit"] = {{"chi2_to_detect", Round(r.noise_fit.chi2_to_detect, 1)},
                                     {"static_error_sd_per_sensor", Round(r.noise_fit.detectable_sd_per_sensor, 2)},
                                     {"static_error_mm_median_sensor", Round(r.noise_fit.detectable_mm_median_sensor, 1)},
                                     {"median_predicted_wear_mm", Round(r.noise_fit.median_predicted_wear_mm, 1)}};
  {
    const Verdict v = DescribeVerdict(r);
    j["verdict"] = {{"kind", v.kind}, {"headline", v.headline}, {"detail", v.detail}};
  }
  // Every configured sensor: used or why not; a used one's latest residual beside its noise.
  j["sensors"] = nlohmann::ordered_json::array();
  j["excluded_sensors"] = nlohmann::ordered_json::array();
  for (const SensorNoise& n : r.sensors) {
    nlohmann::ordered_json x;
    x["sensor_id"] = n.sensor_id;
    x["used"] = n.used;
    if (!n.used) {
      x["excluded_because"] = n.excluded_because;
      j["excluded_sensors"].push_back({{"sensor_id", n.sensor_id}, {"reason", n.excluded_because}});
    }
    if (std::isfinite(n.residual_mm)) {
      x["day"] = Round(n.day, 2);
      x["measured_wear_mm"] = Round(n.measured_wear_mm, 2);
      x["predicted_wear_mm"] = Round(n.predicted_wear_mm, 2);
      x["residual_mm"] = Round(n.residual_mm, 2);
      x["noise_sd_mm"] = Round(n.noise_sd_mm, 2);
      x["residual_z"] = Round(n.z, 2);
      x["noise_parts_mm"] = {{"map_pattern_error", Round(n.map_pattern_mm, 2)},
                             {"map_sampling_noise", Round(n.map_sampling_mm, 2)},
                             {"sensor_floor", Round(n.sensor_floor_mm, 2)},
                             {"reading", Round(n.reading_mm, 2)}};
      x["noise_source"] = n.noise_source;
      x["noise_detail"] = n.noise_detail;
      x["refit_map_error_relative"] = Round(n.refit_map_error_relative, 3);
      x["map_error_prior_relative"] = Round(n.map_error_prior_relative, 3);
      if (std::isfinite(n.map_sd_mm)) {
        x["map_sd_mm"] = Round(n.map_sd_mm, 2);
        x["map_sd_parts_mm"] = {{"sampling_noise", Round(n.map_sd_sampling_mm, 2)},
                                {"smoothing_error", Round(n.map_sd_smoothing_mm, 2)}};
        x["map_error_why"] = n.map_error_why;
        x["map_error_detail"] = n.map_error_detail;
      }
      x["explanation"] = n.explanation;
    }
    j["sensors"].push_back(x);
  }
  j["notes"] = r.notes;
  j["hypotheses"] = r.hypotheses;
  return j;
}

void WritePredictionVtk(const std::filesystem::path& path, const core::Bundle& bundle, const DiagnosisResult& result) {
  if (!result.prediction) throw std::invalid_argument("--predict-vtk needs --predict-at");
  const auto nf = static_cast<Eigen::Index>(bundle.map.face_count());
  Eigen::VectorXd base = Eigen::VectorXd::Zero(nf), improved = Eigen::VectorXd::Zero(nf);
  const auto& p = *result.prediction;
  for (Eigen::Index f = 0; f < nf && static_cast<size_t>(f) < p.face_wear_baseline_mm.size(); ++f) {
    base[f] = p.face_wear_baseline_mm[static_cast<size_t>(f)];
    improved[f] = p.face_wear_improved_mm[static_cast<size_t>(f)];
  }
  core::WriteWearMapVtk(path, bundle.map, {{"wear_mm_baseline", &base}, {"wear_mm_improved", &improved}});
}

}  // namespace lw::diagnosis
