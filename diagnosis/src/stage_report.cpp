// Diagnosis stage 9, what the outputs say about the decisions (stage_report.hpp).
#include "stage_report.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace lw::diagnosis::detail {
namespace {

std::string Join(const std::vector<std::string>& parts, const char* sep) {
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : sep) + p;
  return out;
}

// The sensor's fault names (what excluded readings), in order of appearance.
std::string FaultNames(const SensorData& s) {
  std::vector<std::string> names;
  for (const QualityIssue& q : s.analysis.issues)
    if (q.issue != "dropout" && q.issue != "flicker" &&
        std::find(names.begin(), names.end(), q.issue) == names.end())  // reported only, nothing excluded
      names.push_back(q.issue);
  return Join(names, ", ");
}

nlohmann::ordered_json Failed(const char* test, double value, const char* needed) {
  return {{"test", test}, {"value", Round(value, 3)}, {"needed", needed}};
}

}  // namespace

std::string ExcludedBecause(const SensorData& s, const std::vector<DataQualityIssue>& data_quality) {
  if (s.usable) return "";
  const SensorAnalysis& a = s.analysis;
  if (a.readings.empty()) {
    for (const DataQualityIssue& d : data_quality)
      if (d.sensor_id == s.id && d.issue == "previous_liner") return "no reading of this liner (only a previous liner's)";
    return "no readings: the sensor never reported";
  }
  if (!(s.field.intensity > 1e-6))
    return Fmt("the DEM map predicts no wear at its position (z %.2f m, theta %.0f deg): Eq. 9 has nothing to scale there", s.z,
               s.theta);
  size_t kept = 0, faults = 0;
  double lo = kNaN, hi = kNaN;
  for (size_t k = 0; k < a.readings.size(); ++k) {
    if (k < a.used.size() && !a.used[k]) {
      ++faults;
      continue;
    }
    ++kept;
    lo = std::isfinite(lo) ? std::min(lo, a.readings[k].value_mm) : a.readings[k].value_mm;
    hi = std::isfinite(hi) ? std::max(hi, a.readings[k].value_mm) : a.readings[k].value_mm;
  }
  const std::string names = FaultNames(s);
  std::string why =
      Fmt("%zu loop crossing%s, at least 2 needed to fit a wear rate: ", a.events.size(), a.events.size() == 1 ? "" : "s");
  if (kept == 0) return why + Fmt("all %zu readings were excluded as faults (%s)", faults, names.c_str());
  why += lo == hi ? Fmt("its %zu kept reading%s all read %.0f mm (no wear seen yet)", kept, kept == 1 ? "" : "s", lo)
                  : Fmt("its %zu kept readings lie between %.0f and %.0f mm (the liner has barely worn there)", kept, lo, hi);
  if (faults > 0) why += Fmt(", %zu more excluded as faults (%s)", faults, names.c_str());
  return why;
}

std::vector<SensorNoise> ExplainSensors(const ProblemSetup& setup, const Baseline& base, const NullModel& null,
                                        const std::vector<DataQualityIssue>& data_quality, const std::string& tau_source) {
  const Thresholds th;
  const Problem& prob = setup.prob;
  Eigen::MatrixXd w;
  Simulate(base.spec, base.eq9.x, prob.points, prob.grid, w);
  std::vector<SensorNoise> out;
  for (const SensorData& s : setup.sensors) {
    SensorNoise n;
    n.sensor_id = s.id;
    n.used = s.usable;
    n.excluded_because = ExcludedBecause(s, data_quality);
    if (!s.usable || s.usable_index < 0 || static_cast<size_t>(s.usable_index) >= prob.sensor_obs.size() ||
        prob.sensor_obs[static_cast<size_t>(s.usable_index)].empty()) {
      out.push_back(std::move(n));
      continue;
    }
    const auto ui = static_cast<size_t>(s.usable_index);
    const Obs& o = prob.obs[prob.sensor_obs[ui].back()];
    const double pred = Interp(w, o);
    n.day = o.t;
    n.measured_wear_mm = o.raw;
    n.predicted_wear_mm = pred;
    n.residual_mm = o.raw - pred;
    // The mismatch test's noise at this observation: the event's own sigma and the sensor's
    // intensity error (prior sd sigma_u, relative) on the predicted wear; sigma_u^2 is the map's
    // sampling noise^2 + its pattern error^2 + the floor^2 (CalibrateNoise).
    const double su = ui < prob.sigma_u.size() ? prob.sigma_u[ui] : 0.0;
    const double rs = s.field.rel_sampling, floor = th.u_floor_rel;
    const double tau = std::sqrt(std::max(0.0, su * su - rs * rs - floor * floor));
    const double p = std::max(pred, 0.0);
    n.map_sampling_mm = rs * p;
    n.map_pattern_mm = tau * p;
    n.sensor_floor_mm = floor * p;
    n.reading_mm = o.sigma;
    n.noise_sd_mm = std::sqrt(o.sigma * o.sigma + su * su * p * p);
    n.z = n.noise_sd_mm > 0 ? n.residual_mm / n.noise_sd_mm : kNaN;
    n.refit_map_error_relative = ui < null.fit.u.size() ? null.fit.u[ui] : kNaN;
    n.map_error_prior_relative = su;
    const double parts[4] = {n.map_pattern_mm, n.map_sampling_mm, n.sensor_floor_mm, n.reading_mm};
    const int largest = static_cast<int>(std::max_element(parts, parts + 4) - parts);
    switch (largest) {
      case 0:
        n.noise_source = "map_pattern_error";
        if (tau_source == "scan")
          n.noise_detail = Fmt("the map's pattern error, %.0f %% of the predicted wear, measured on the scan's cells", 100 * tau);
        else if (tau_source == "sensors")
          n.noise_detail =
              Fmt("the map's pattern error, %.0f %% of the predicted wear, measured from the sensors' spread about their rows' "
                  "scales",
                  100 * tau);
        else
          n.noise_detail =
              Fmt("the map's pattern error, %.0f %% of the predicted wear, taken from the map's own cross-validated smoothing "
                  "error (neither a scan nor the sensors' spread measured it smaller): the smoothed DEM map does not resolve "
                  "the wear pattern",
                  100 * tau);
        break;
      case 1:
        n.noise_detail =
            Fmt("the DEM map's sampling noise at the sensor, %.0f %% of the predicted wear: the faces' noise between the run's "
                "time windows through the smoothing kernel (a longer DEM run narrows it)",
                100 * rs);
        n.noise_source = "map_sampling_noise";
        break;
      case 2:
        n.noise_source = "sensor_floor";
        n.noise_detail = "the 2 % per-sensor floor of the map's error (placement, local geometry)";
        break;
      default:
        n.noise_source = "reading";
        n.noise_detail = "the reading's own: the 1 mm loop ladder, the time inside the report interval, the 2 % model floor";
    }
    out.push_back(std::move(n));
  }
  return out;
}

NoiseFit JudgeNoiseFit(const nlohmann::ordered_json& noise, double mismatch_z, const std::vector<SensorNoise>& sensors) {
  constexpr double kBlindRelative = 0.5;
  std::vector<std::string> why;
  auto num = [&](const char* key, double fallback) {
    return noise.contains(key) && noise[key].is_number() ? noise[key].get<double>() : fallback;
  };
  auto under = [&](const char* chi2_key, const char* count_key, const char* what) {
    const double c = num(chi2_key, 1.0);
    if (num(count_key, 0.0) > 0 && c < 0.25)
      why.push_back(c > 0 ? Fmt("chi-square per %s %.3g (1 expected: the modelled noise sd is %.0f times the scatter the data "
                                "show about the refit baseline)",
                                what, c, 1.0 / std::sqrt(c))
                          : Fmt("chi-square per %s 0 (1 expected)", what));
  };
  under("baseline_chi2_per_sensor_event", "sensor_events", "sensor event");
  under("baseline_chi2_per_scan_cell", "scan_cells", "scan cell");
  if (mismatch_z < -4)
    why.push_back(
        Fmt("chi-square excess z %.1f (far below 0: the data agree with the refit far better than the noise model says they "
            "can)",
            mismatch_z));
  NoiseFit f;
  f.fits = why.empty();
  f.detail = Join(why, "; ");

  // Blind: the noise as large as the wear.
  std::vector<std::string> blind;
  const double tau = num("map_pattern_error_relative", 0.0);
  const std::string source = noise.contains("map_pattern_error_source") && noise["map_pattern_error_source"].is_string()
                                 ? noise["map_pattern_error_source"].get<std::string>()
                                 : std::string();
  double smoothing = kNaN;
  if (noise.contains("map_model") && noise["map_model"].is_object() && noise["map_model"].contains("smoothing_error_relative") &&
      noise["map_model"]["smoothing_error_relative"].is_number())
    smoothing = noise["map_model"]["smoothing_error_relative"].get<double>();
  if (tau > kBlindRelative) {
    const std::string from = source == "scan"      ? "measured on the scan's cells"
                             : source == "sensors" ? "measured from the sensors' spread about their rows' scales"
                                                   : "taken from the map's own cross-validated smoothing error";
    std::string text = Fmt("the map's pattern error is %.0f %% of the predicted wear (%s", 100 * tau, from.c_str());
    if (std::isfinite(smoothing) && source != "map cross-validation")
      text += Fmt("; the map's own smoothing error is %.0f %%", 100 * smoothing);
    blind.push_back(text + "): the smoothed DEM map hardly describes this liner's wear pattern");
  }
  std::vector<double> ratio;
  for (const SensorNoise& n : sensors)
    if (n.used && n.predicted_wear_mm > 1.0 && std::isfinite(n.noise_sd_mm)) ratio.push_back(n.noise_sd_mm / n.predicted_wear_mm);
  if (!ratio.empty()) {
    std::sort(ratio.begin(), ratio.end());
    const double median = ratio[ratio.size() / 2];
    if (median > kBlindRelative)
      blind.push_back(Fmt("at the median sensor the noise model allows %.0f %% of the predicted wear (1 sd)", 100 * median));
  }
  f.blind = !blind.empty();
  f.blind_detail = Join(blind, "; ");
  return f;
}

void AnnotateHypotheses(nlohmann::ordered_json& table, const Hypotheses& h, double log_n) {
  const Thresholds th;
  const std::vector<ModelEval>& evals = h.evals;
  for (size_t k = 0; k < evals.size() && k < table.size(); ++k) {
    const ModelEval& ev = evals[k];
    nlohmann::ordered_json& row = table[k];
    const bool chosen = h.best >= 0 && static_cast<size_t>(h.best) == k;
    row["verdict"] = chosen ? "chosen" : ev.accepted ? "accepted" : "rejected";
    if (ev.accepted) {
      if (chosen) continue;
      if (h.encompassing.explained_away >= 0 && static_cast<size_t>(h.encompassing.explained_away) == k &&
          h.encompassing.by >= 0) {
        const std::string by = evals[static_cast<size_t>(h.encompassing.by)].full.spec.Name();
        row["not_chosen_because"] =
            Fmt("explained away by %s: fitted together, its effect falls within one standard error of nothing while %s's "
                "stays, and %s alone predicts the held-out data at least as well",
                by.c_str(), by.c_str(), by.c_str());
      } else if (h.best >= 0) {
        const ModelEval& best = evals[static_cast<size_t>(h.best)];
        row["not_chosen_because"] = Fmt("%s scores higher (delta BIC + held-out gain %.1f against %.1f)",
                                        best.full.spec.Name().c_str(), best.score, ev.score);
      }
      continue;
    }
    std::vector<std::string> why;
    nlohmann::ordered_json failed = nlohmann::ordered_json::array();
    if (!(ev.delta_bic > th.min_delta_bic)) {
      why.push_back(Fmt("information gain delta BIC %.1f (needs > %.0f)", ev.delta_bic, th.min_delta_bic));
      failed.push_back(Failed("delta_bic", ev.delta_bic, "> 10"));
    }
    if (!(ev.ho_gain > th.min_holdout_gain)) {
      why.push_back(Fmt("held-out chi-square gain %.1f (needs > %.0f)", ev.ho_gain, th.min_holdout_gain));
      failed.push_back(Failed("holdout_gain", ev.ho_gain, "> 4"));
    }
    if (!(ev.ho_rel > th.min_holdout_rel)) {
      why.push_back(Fmt("held-out improvement %.1f %% (needs > %.0f %%)", 100 * ev.ho_rel, 100 * th.min_holdout_rel));
      failed.push_back(Failed("holdout_improvement", ev.ho_rel, "> 0.03"));
    }
    if (!(ev.significance > th.min_significance)) {
      why.push_back(Fmt("effect size %.1f standard errors from zero (needs > %.0f): the data do not determine its size",
                        ev.significance, th.min_significance));
      failed.push_back(Failed("significance", ev.significance, "> 2"));
    }
    if (why.empty() && k >= h.singles && k - h.singles < h.pair_parts.size()) {
      // The pair rules (ApplyPairRules): beat both single effects, and no accepted single effect
      // predicts the held-out data better.
      const auto [pa, pb] = h.pair_parts[k - h.singles];
      for (size_t part : {pa, pb}) {
        const ModelEval& single = evals[part];
        const double gain = (single.full.chi2 - ev.full.chi2) / h.dispersion -
                            static_cast<double>(ev.full.spec.ParamCount() - single.full.spec.ParamCount()) * log_n;
        if (gain < th.pair_delta_bic) {
          why.push_back(
              Fmt("delta BIC over %s alone %.1f (needs >= %.0f)", single.full.spec.Name().c_str(), gain, th.pair_delta_bic));
          failed.push_back(Failed("pair_delta_bic", gain, ">= 10"));
          failed.back()["against"] = single.full.spec.Name();
        }
        if (ev.ho_chi2 > single.ho_chi2) {
          why.push_back(Fmt("held-out chi-square %.1f, worse than %s alone (%.1f)", ev.ho_chi2, single.full.spec.Name().c_str(),
                            single.ho_chi2));
          failed.push_back(Failed("pair_holdout_chi2", ev.ho_chi2, "<= its single effects'"));
          failed.back()["against"] = single.full.spec.Name();
        }
      }
      for (size_t m = 0; m < h.singles; ++m)
        if (evals[m].accepted && ev.ho_chi2 > evals[m].ho_chi2 && m != pa && m != pb) {
          why.push_back(Fmt("held-out chi-square %.1f, worse than the accepted %s (%.1f)", ev.ho_chi2,
                            evals[m].full.spec.Name().c_str(), evals[m].ho_chi2));
          failed.push_back(Failed("parsimony", ev.ho_chi2, "<= every accepted single effect's"));
          failed.back()["against"] = evals[m].full.spec.Name();
        }
    }
    if (why.empty()) {
      // Only the squeeze-wear shape rule (RequireStressShape) is left: it refuses squeeze_wear
      // and every pair holding it, with a note.
      why.push_back(
          "the map smoothed like the normal stress, in the stress's place, fits about as well (see the notes): what it "
          "fitted is the map's smoothing scale, not normal stress");
      failed.push_back({{"test", "stress_shape"}, {"needed", "better than the map smoothed like the stress"}});
    }
    row["rejected_because"] = Join(why, "; ");
    row["failed_tests"] = failed;
  }
}

}  // namespace lw::diagnosis::detail
