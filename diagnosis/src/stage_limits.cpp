// Detection limits (stage_limits.hpp).
#include "stage_limits.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace lw::diagnosis::detail {
namespace {

// What a planner calls the effect and its strength.
struct LimitWords {
  const char* effect;
  const char* parameter;  // the JSON's parameter name
  const char* symbol;
  const char* what;
};

LimitWords WordsOf(Effect e) {
  switch (e) {
    case Effect::kWorkHardening:
      return {"work hardening", "h", "h", "wear-rate reduction once hardened"};
    case Effect::kHardnessGradient:
      return {"a hardness gradient", "g", "g", "wear-rate increase at depth"};
    case Effect::kSqueezeWear:
      return {"squeeze wear", "beta", "beta", "squeeze wear per unit normal stress"};
    case Effect::kProfileEvolution:
      return {"a profile change (tilt)", "p_per_100_days", "p", "top vs bottom rate change per 100 days"};
    case Effect::kProfileShift:
      return {"a profile change (shift)", "shift_per_100_days", "v", "concave heights per 100 days"};
    case Effect::kFeedSegregation:
      return {"feed segregation", "amplitude", "A", "circumferential wear-rate amplitude"};
    case Effect::kThroughputVariation:
      return {"throughput-driven wear", "phi", "phi", "share of the wear rate following tonnage"};
  }
  return {"?", "?", "?", "?"};
}

// The main parameter's standard error as Significance judges it (the dispersion's inflation; feed
// segregation's amplitude with the map's own first-harmonic error).
double MainStderr(const FitResult& f, Effect e, double dispersion, double map_harmonic1_sd) {
  const int o = f.spec.Offset(e);
  if (o < 0 || f.stderr_given_shape.size() != f.x.size()) return kNaN;
  const double inflate = std::sqrt(std::max(1.0, dispersion));
  if (e == Effect::kFeedSegregation) {
    const double se_fit = std::hypot(f.stderr_given_shape[o], f.stderr_given_shape[o + 1]) / std::sqrt(2.0) * inflate;
    return std::hypot(se_fit, std::max(0.0, map_harmonic1_sd));
  }
  return f.stderr_given_shape[o] * inflate;
}

}  // namespace

std::vector<DetectionLimit> DetectionLimits(const Hypotheses& h, double log_n, double map_harmonic1_sd,
                                            const std::vector<Finding>& findings, double last_day) {
  const Thresholds th;
  std::vector<DetectionLimit> out;
  for (size_t k = 0; k < h.singles; ++k) {
    const FitResult& f = h.evals[k].full;
    if (f.spec.effects.size() != 1) continue;
    const Effect e = f.spec.effects[0];
    const double se = MainStderr(f, e, h.dispersion, map_harmonic1_sd);
    if (!(se > 0) || !std::isfinite(se)) continue;
    // The bar: the information criterion's gain (z^2 = delta chi-square, less the parameters'
    // charge) and the size test; one standard error above it is found about 84 % of the time.
    const double charge = static_cast<double>(EffectParams(e).size()) * log_n;
    const double z_needed = std::max(th.min_significance, std::sqrt(th.min_delta_bic + charge));
    DetectionLimit lim;
    lim.effect = EffectName(e);
    lim.form = FormName(e);
    lim.parameter = WordsOf(e).parameter;
    lim.stderr_ = se;
    lim.z_needed = z_needed;
    lim.min_detectable = se * (z_needed + 1.0);
    lim.until_day = last_day;
    auto same = std::find_if(out.begin(), out.end(), [&](const DetectionLimit& l) { return l.effect == lim.effect; });
    if (same != out.end()) {
      if (same->min_detectable <= lim.min_detectable) continue;
      *same = lim;
    } else {
      out.push_back(lim);
    }
  }
  for (DetectionLimit& lim : out) {
    for (const Finding& fi : findings)
      if (fi.effect == lim.effect) lim.named = true;
    Effect e = Effect::kWorkHardening;
    for (int i = 0; i < kEffectCount; ++i)
      if (lim.form == FormName(static_cast<Effect>(i))) e = static_cast<Effect>(i);
    const LimitWords w = WordsOf(e);
    // Beyond the effect's physical range no strength it can take would show: say so, not a number
    // no liner can have.
    const double range = std::fabs(EffectParams(e)[0].upper);
    char buf[400];
    if (lim.min_detectable > range)
      std::snprintf(buf, sizeof buf,
                    "%s would not show by day %.0f with these sensors and scans at any strength in its range (%s up to "
                    "%.3g; it would need %s = %.3g: standard error %.2g, %.1f standard errors to be named)",
                    w.effect, lim.until_day, w.symbol, range, w.symbol, lim.min_detectable, lim.stderr_, lim.z_needed);
    else
      std::snprintf(buf, sizeof buf,
                    "%s below %s = %.3g (%s) would not show by day %.0f with these sensors and scans "
                    "(standard error %.2g; it needs %.1f standard errors to be named)",
                    w.effect, w.symbol, lim.min_detectable, w.what, lim.until_day, lim.stderr_, lim.z_needed);
    lim.sentence = buf;
    // What narrows it: the standard error falls with more independent evidence of the effect's
    // shape; its time shape comes with months of readings, its spatial shape with a scan.
    lim.would_show_with = e == Effect::kFeedSegregation || e == Effect::kSqueezeWear || e == Effect::kHardnessGradient
                              ? "a laser scan (the effect's shape over the liner), or sensors at other angles or depths"
                              : "more months of readings (the effect's time course), or a second scan later";
  }
  return out;
}

}  // namespace lw::diagnosis::detail
