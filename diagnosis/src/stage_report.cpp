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

// Area-weighted ring mean of the map's (outlier-capped) raw faces with z in [lo, hi]; NaN when no face.
double RingMean(const core::MapModel& m, double lo, double hi) {
  const core::WearMap& map = *m.map;
  double sw = 0, sa = 0;
  for (Eigen::Index i = 0; i < map.z.size() && i < m.clean.size(); ++i)
    if (map.z[i] >= lo && map.z[i] <= hi) {
      sw += map.areas[i] * m.clean[i];
      sa += map.areas[i];
    }
  return sa > 0 ? sw / sa : kNaN;
}

// Area-weighted mean of the raw (outlier-capped) faces within `reach` (z and arc length) of a
// point, and its standard error from the faces' noise law; NaN when no face.
struct Local {
  double mean = kNaN, sd = kNaN;
};
Local LocalMean(const core::MapModel& m, double z, double theta_deg, double reach) {
  const core::WearMap& map = *m.map;
  double sw = 0, sa = 0, sv = 0;
  for (Eigen::Index i = 0; i < map.z.size() && i < m.clean.size(); ++i) {
    const double arc = map.radius[i] * AngleDiffDeg(map.theta_deg[i], theta_deg) * M_PI / 180.0;
    if (std::fabs(map.z[i] - z) <= reach && std::fabs(arc) <= reach) {
      sw += map.areas[i] * m.clean[i];
      sa += map.areas[i];
      sv += map.areas[i] * map.areas[i] * m.FaceVariance(m.clean[i]);
    }
  }
  Local l;
  if (sa > 0) {
    l.mean = sw / sa;
    l.sd = std::sqrt(sv) / sa;
  }
  return l;
}

// The kernel's scale along z at a point: the nearest face's local scale (the map model's ICI), else
// the global one.
double KernelAt(const core::MapModel& m, double z, double theta_deg) {
  if (m.local_bandwidth_m.size() != m.map->z.size() || m.map->z.size() == 0) return m.bandwidth_m;
  Eigen::Index best = 0;
  double best_d = 1e300;
  for (Eigen::Index i = 0; i < m.map->z.size(); ++i) {
    const double arc = m.map->radius[i] * AngleDiffDeg(m.map->theta_deg[i], theta_deg) * M_PI / 180.0;
    const double d = (m.map->z[i] - z) * (m.map->z[i] - z) + arc * arc;
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return m.local_bandwidth_m[best] > 0 ? m.local_bandwidth_m[best] : m.bandwidth_m;
}

// Where the test's noise at a sensor comes from, in words (SensorNoise::noise_detail).
std::string NoiseDetail(const std::string& source, const std::string& tau_source, double tau, double rs) {
  if (source == "map_pattern_error") {
    if (tau_source == "scan")
      return Fmt("the map's pattern error, %.0f %% of the predicted wear, measured on the scan's cells", 100 * tau);
    if (tau_source == "sensors")
      return Fmt(
          "the map's pattern error, %.0f %% of the predicted wear, measured from the sensors' spread about their rows' "
          "scales (these residuals themselves, so it cannot tell a map error from a real one)",
          100 * tau);
    return Fmt(
        "the map's pattern error, %.0f %% of the predicted wear, taken from the map's own cross-validated smoothing "
        "error (neither a scan nor the sensors' spread measured it smaller): the smoothed DEM map does not resolve "
        "the wear pattern",
        100 * tau);
  }
  if (source == "map_sampling_noise")
    return Fmt(
        "the DEM map's sampling noise at the sensor, %.0f %% of the predicted wear: the faces' noise between the run's "
        "time windows through the smoothing kernel (a longer DEM run narrows it)",
        100 * rs);
  if (source == "sensor_floor") return "the 2 % per-sensor floor of the map's error (placement, local geometry)";
  return "the reading's own: the 1 mm loop ladder, the time inside the report interval, the 2 % model floor";
}

// SensorNoise::explanation.
std::string ExplainResidual(const SensorNoise& n) {
  std::string s =
      Fmt("sensor %s is off by %+.1f mm (measured - predicted wear, day %.0f); the mismatch test allows %.1f mm "
          "(1 sd) there, %.1f sd, mostly %s",
          n.sensor_id.c_str(), n.residual_mm, n.day, n.noise_sd_mm, std::fabs(n.z), n.noise_detail.c_str());
  if (!std::isfinite(n.map_sd_mm)) return s;
  s += Fmt("; the map's own standard error at sensor %s is %.1f mm (%.0f %% of the predicted wear), %s", n.sensor_id.c_str(),
           n.map_sd_mm, n.predicted_wear_mm > 0 ? 100 * n.map_sd_mm / n.predicted_wear_mm : 0.0, n.map_error_detail.c_str());
  const double ratio = n.map_sd_mm > 0 ? std::fabs(n.residual_mm) / n.map_sd_mm : kNaN;
  if (std::isfinite(ratio))
    s += ratio <= 2 ? Fmt("; the residual is %.1f times that: within what the map itself cannot resolve there", ratio)
                    : Fmt("; the residual is %.1f times that: more than the map's own error there explains", ratio);
  return s;
}

}  // namespace

MapError ExplainMapError(const MapFields& f, const SensorData& s) {
  MapError e;
  e.sd_rel = s.field.rel_noise;
  e.sampling_rel = std::min(s.field.rel_sampling, s.field.rel_noise);
  const core::MapModel& m = f.model;
  const bool have_map = m.map && m.map->face_count() > 0 && f.noise_estimated;
  const core::MapModel::Point at = have_map ? m.At(s.z, s.theta) : core::MapModel::Point{};
  if (at.intensity > 0) {
    // The map model's own figures, not capped at 100 % as the fit's intensity error is.
    const double q = QuantisationRel(f, s.field.intensity);
    e.sd_rel = std::hypot(at.sd / at.intensity, q);
    e.sampling_rel = std::hypot(at.noise_sd / at.intensity, q);
  }
  e.smoothing_rel = std::sqrt(std::max(0.0, e.sd_rel * e.sd_rel - e.sampling_rel * e.sampling_rel));
  if (!have_map) {
    e.why = "sampling_noise";
    e.detail = Fmt("the map has too few faces to measure its own noise: %.0f %% assumed", 100 * e.sd_rel);
    return e;
  }
  // Where the local scale stopped below the global one its bias is counted as large as its noise
  // (core::MapModel): a tie is the smoothing's, the map changing faster than the kernel there.
  if (e.sampling_rel > e.smoothing_rel * (1 + 1e-9)) {
    e.why = "sampling_noise";
    const double faces = std::max(1.0, static_cast<double>(s.field.faces));
    e.detail =
        Fmt("mostly its sampling noise: one face of the DEM run scatters by %.0f %% (%s) and the kernel averages "
            "about %.0f faces here; a longer DEM run narrows it",
            100 * m.face_cv, m.noise_source.c_str(), faces);
    return e;
  }
  const double h = std::max(KernelAt(m, s.z, s.theta), f.face_size_m);
  const double here = RingMean(m, s.z - 0.5 * h, s.z + 0.5 * h);
  // The edges within the kernel's reach (3 sd): the concave's bottom is its discharge edge.
  struct Edge {
    const char* name;
    double distance;
    double lo, hi;
  };
  const Edge edges[2] = {{"discharge", s.z - f.z_bottom, f.z_bottom, f.z_bottom + h},
                         {"feed", f.z_top - s.z, f.z_top - h, f.z_top}};
  const Edge* edge = nullptr;
  double edge_ratio = 1;
  for (const Edge& g : edges) {
    if (!(g.distance < 3 * h) || !(here > 0)) continue;
    const double ratio = RingMean(m, g.lo, g.hi) / here;
    if (std::isfinite(ratio) && std::fabs(std::log(ratio)) > std::fabs(std::log(edge_ratio))) {
      edge = &g;
      edge_ratio = ratio;
    }
  }
  if (edge && (edge_ratio > 1.5 || edge_ratio < 1 / 1.5)) {
    e.why = "edge_band";
    e.detail =
        Fmt("mostly its smoothing's error: the %s-edge band is unresolved: the DEM's ring-mean wear within %.2f m of "
            "the %s edge is %.1f times that at the sensor's height, %.2f m away, inside the kernel's reach (3 x its "
            "%.2f m sd along z), so the smoothed map there mixes the two",
            edge->name, h, edge->name, edge_ratio, edge->distance, h);
    return e;
  }
  // The raw faces around the sensor against the smoothed value there: a difference beyond twice
  // their own mean's noise is structure the kernel flattens.
  const Local local = LocalMean(m, s.z, s.theta, h);
  if (at.intensity > 0 && std::isfinite(local.mean) && std::fabs(local.mean - at.intensity) > 2 * local.sd) {
    e.why = "local_structure";
    e.detail =
        Fmt("mostly its smoothing's error: the raw DEM faces within %.2f m of the sensor wear %.0f %% %s than the "
            "smoothed map says there (%.1f times their own mean's noise): structure finer than the kernel's %.2f m "
            "sd that the smoothed map does not resolve",
            h, 100 * std::fabs(local.mean / at.intensity - 1), local.mean > at.intensity ? "more" : "less",
            std::fabs(local.mean - at.intensity) / std::max(local.sd, 1e-12), h);
    return e;
  }
  e.why = "smoothing";
  e.detail =
      Fmt("mostly its smoothing's error: the map's cross-validated smoothing error is %.0f %% of the wear over the "
          "liner (kernel sd %.2f m along z): the smoothed DEM map does not follow the DEM's own pattern closer than that",
          100 * m.smoothing_error_rel, h);
  return e;
}

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
    static const char* const kSources[4] = {"map_pattern_error", "map_sampling_noise", "sensor_floor", "reading"};
    n.noise_source = kSources[std::max_element(parts, parts + 4) - parts];
    n.noise_detail = NoiseDetail(n.noise_source, tau_source, tau, rs);
    const MapError me = ExplainMapError(setup.fields, s);
    n.map_sd_mm = me.sd_rel * p;
    n.map_sd_sampling_mm = me.sampling_rel * p;
    n.map_sd_smoothing_mm = me.smoothing_rel * p;
    n.map_error_why = me.why;
    n.map_error_detail = me.detail;
    n.explanation = ExplainResidual(n);
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
  // The test's noise is learned per observation type (noise.mismatch_calibration): it fits unless a
  // type's calibrated chi-square is still far below 1 (a type too small to learn its scale, whose
  // modelled noise is far wider than its scatter).
  auto under = [&](const char* type, const char* what) {
    if (!noise.contains("mismatch_calibration") || !noise["mismatch_calibration"].contains(type)) return;
    const auto& t = noise["mismatch_calibration"][type];
    const double c = t.value("chi2_per_observation", 1.0);
    if (c < 0.25)
      why.push_back(c > 0 ? Fmt("chi-square per %s %.3g (1 expected: the noise sd is %.0f times the scatter the data "
                                "show about the refit baseline)",
                                what, c, 1.0 / std::sqrt(c))
                          : Fmt("chi-square per %s 0 (1 expected)", what));
  };
  under("sensor_events", "sensor event");
  under("sensor_priors", "sensor's intensity error");
  under("scan_cells", "scan cell");
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

void AddExcludedEvidence(std::vector<SensorNoise>& sensors, const std::vector<SensorCurve>& curves) {
  for (SensorNoise& n : sensors) {
    if (n.used) continue;
    const auto c = std::find_if(curves.begin(), curves.end(), [&](const SensorCurve& x) { return x.sensor_id == n.sensor_id; });
    if (c == curves.end() || c->model_days.size() < 2 || c->baseline_thickness_mm.size() != c->model_days.size()) continue;
    double day = kNaN, reading = kNaN;
    for (size_t k = 0; k < c->reading_days.size() && k < c->reading_mm.size(); ++k)
      if ((k >= c->reading_used.size() || c->reading_used[k]) && std::isfinite(c->reading_mm[k]) &&
          (!std::isfinite(day) || c->reading_days[k] >= day)) {
        day = c->reading_days[k];
        reading = c->reading_mm[k];
      }
    if (!std::isfinite(day)) continue;
    // The baseline's thickness at that day, linear between its time steps.
    const std::vector<double>& t = c->model_days;
    const size_t k = static_cast<size_t>(std::upper_bound(t.begin(), t.end(), day) - t.begin());
    const size_t a = std::clamp<size_t>(k, 1, t.size() - 1) - 1;
    const double f = std::clamp((day - t[a]) / std::max(t[a + 1] - t[a], 1e-12), 0.0, 1.0);
    const double base = c->baseline_thickness_mm[a] + f * (c->baseline_thickness_mm[a + 1] - c->baseline_thickness_mm[a]);
    if (!std::isfinite(base)) continue;
    const double worn_lo = std::max(0.0, c->thickness_new_mm - reading - 1),
                 worn_hi = std::max(0.0, c->thickness_new_mm - reading);
    const std::string worn = worn_hi <= 0 ? std::string("no wear") : Fmt("%.0f to %.0f mm of wear", worn_lo, worn_hi);
    n.excluded_because +=
        Fmt("; its last reading (day %.0f) is %.0f mm, %s, where the baseline (Eq. 9, row scales from the "
            "other sensors) predicts %.1f mm of wear by then",
            day, reading, worn.c_str(), c->thickness_new_mm - base);
  }
}

void AddDetectionLimit(NoiseFit& fit, double mismatch_z, double dof, const std::vector<SensorNoise>& sensors) {
  const Thresholds th;
  std::vector<double> sd, wear;
  for (const SensorNoise& n : sensors)
    if (n.used && std::isfinite(n.noise_sd_mm) && n.noise_sd_mm > 0 && std::isfinite(n.predicted_wear_mm)) {
      sd.push_back(n.noise_sd_mm);
      wear.push_back(n.predicted_wear_mm);
    }
  if (sd.empty() || !(dof > 0) || !std::isfinite(mismatch_z)) return;
  std::sort(sd.begin(), sd.end());
  std::sort(wear.begin(), wear.end());
  fit.chi2_to_detect = std::max(0.0, (th.mismatch_z - mismatch_z) * std::sqrt(2.0 * dof));
  fit.detectable_sd_per_sensor = std::sqrt(fit.chi2_to_detect / static_cast<double>(sd.size()));
  fit.detectable_mm_median_sensor = fit.detectable_sd_per_sensor * sd[sd.size() / 2];
  fit.median_predicted_wear_mm = wear[wear.size() / 2];
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
      std::string limit;
      for (Effect e : ev.full.spec.effects) {
        std::string one;
        if (AtLimit(ev.full, e, &one)) limit += (limit.empty() ? "" : "; ") + std::string(EffectName(e)) + ": " + one;
      }
      if (!limit.empty()) {
        why.push_back("effect size at a bound (needs a size inside its physical range): " + limit);
        failed.push_back(Failed("at_limit", ev.significance, "inside its physical range"));
      } else {
        why.push_back(Fmt("effect size %.1f standard errors from zero (needs > %.0f): the data do not determine its size",
                          ev.significance, th.min_significance));
        failed.push_back(Failed("significance", ev.significance, "> 2"));
      }
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
    // A held-out gain that passed is named first: it alone does not make a finding.
    const bool held_out_passed = ev.ho_gain > th.min_holdout_gain && ev.ho_rel > th.min_holdout_rel;
    row["rejected_because"] =
        (held_out_passed ? Fmt("the held-out improvement %.1f %% passes, but ", 100 * ev.ho_rel) : std::string()) +
        Join(why, "; ");
    row["failed_tests"] = failed;
  }
}

}  // namespace lw::diagnosis::detail

namespace lw::diagnosis {
namespace {

// What "no mismatch" can mean with these data (NoiseFit's detection limit), in a sentence; empty
// when not known.
std::string DetectionLimitText(const DiagnosisResult& r) {
  const NoiseFit& f = r.noise_fit;
  if (!std::isfinite(f.detectable_mm_median_sensor) || !std::isfinite(f.chi2_to_detect)) return "";
  size_t used = 0;
  for (const SensorNoise& n : r.sensors) used += n.used && std::isfinite(n.noise_sd_mm) ? 1 : 0;
  std::string s = detail::Fmt(
      "A mismatch is called at z above 4; from z %.1f that needs the refit's chi-square to rise by about %.0f: a static error of "
      "about %.1f noise sd at each of the %zu used sensors, about %.0f mm of wear at the median sensor",
      r.mismatch_z_score, f.chi2_to_detect, f.detectable_sd_per_sensor, used, f.detectable_mm_median_sensor);
  if (std::isfinite(f.median_predicted_wear_mm) && f.median_predicted_wear_mm > 0)
    s += detail::Fmt(" (%.0f %% of its predicted wear of %.0f mm)",
                     100 * f.detectable_mm_median_sensor / f.median_predicted_wear_mm, f.median_predicted_wear_mm);
  return s + ". A smaller error passes as noise.";
}

}  // namespace

Verdict DescribeVerdict(const DiagnosisResult& r) {
  Verdict v;
  const NoiseFit& f = r.noise_fit;
  const std::string misfit = f.fits ? std::string() : "The noise model does not fit these data: " + f.detail + ".";
  if (!r.findings.empty()) {
    const Finding& top = r.findings.front();
    if (top.effect == kUnexplained) {
      v.kind = "mismatch_unexplained";
      v.headline = "Mismatch, unexplained";
      v.detail = detail::Fmt(
          "the recordings disagree with the DEM-based prediction beyond the noise (z %.1f), but none of the "
          "modelled effects is convincing: see the residual maps and the mismatch regions.",
          r.mismatch_z_score);
    } else {
      v.kind = "mismatch_explained";
      v.headline = "Mismatch found";
      v.detail = detail::Fmt("most supported explanation: %s (confidence %.2f)", top.effect.c_str(), top.confidence);
      for (size_t k = 1; k < r.findings.size(); ++k)
        v.detail += detail::Fmt("%s%s (%.2f)", k == 1 ? "; also " : ", ", r.findings[k].effect.c_str(), r.findings[k].confidence);
      v.detail += ".";
    }
    if (!f.fits) v.detail += " " + misfit + " Every gain is measured against it: weigh the confidence accordingly.";
    return v;
  }
  const std::string limit = DetectionLimitText(r);
  if (!f.fits) {
    v.kind = "noise_model_does_not_fit";
    v.headline = "Not tested: the noise model does not fit these data";
    v.detail = f.detail +
               ". The test measured the residuals against a noise wider than they scatter, so it finds no mismatch whatever "
               "the liner did inside that noise: this is no evidence that the DEM-based prediction agrees with the "
               "recordings.";
    if (f.blind) v.detail += " The noise is also as large as the wear: " + f.blind_detail + ".";
    if (!limit.empty()) v.detail += " " + limit;
    return v;
  }
  if (f.blind) {
    v.kind = "not_testable";
    v.headline = "No mismatch detected, but this test could not have seen one";
    v.detail = f.blind_detail + ". Read it as not testable with this map, not as agreement." + (limit.empty() ? "" : " " + limit);
    return v;
  }
  v.kind = "no_mismatch";
  v.headline = "No mismatch beyond the noise";
  v.detail =
      detail::Fmt("the DEM-based prediction agrees with the recordings within the noise model (z %.1f).", r.mismatch_z_score) +
      (limit.empty() ? "" : " " + limit);
  return v;
}

}  // namespace lw::diagnosis
