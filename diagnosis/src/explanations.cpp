// The findings' explanations (explanations.hpp).
#include "explanations.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace lw::diagnosis::detail {
namespace {

double Param(const FitResult& f, Effect e, size_t k) {
  return f.x[f.spec.Offset(e) + static_cast<Eigen::Index>(k)];
}
double ParamSe(const FitResult& f, Effect e, size_t k) {
  return f.stderr_x[f.spec.Offset(e) + static_cast<Eigen::Index>(k)];
}

void DescribeWorkHardening(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  const double h = Param(f, e, 0), tau = std::exp(Param(f, e, 1));
  out.parameters["h"] = Round(h, 3);
  out.parameters["h_stderr"] = Round(ParamSe(f, e, 0), 3);
  out.parameters["tau_days"] = Round(tau, 2);
  out.parameters["tau_days_stderr"] = Round(tau * ParamSe(f, e, 1), 2);
  out.parameters["saturation_days"] = Round(3.0 * tau, 1);
  out.parameters["weighted_by"] = c.has_normal ? "normal_stress_average" : "uniform (map has no normal stress)";
  out.explanation = std::string("The liner wore less than the DEM predicts as the campaign went on") +
                    (c.has_normal ? " where normal stress (impact) is high" : "") +
                    Fmt(": the wear rate fell by %.0f %% where impact is strongest, saturating in about %.0f "
                        "days (time constant %.1f days), as impact hardening of manganese steel does "
                        "(wear ~ 1/hardness).",
                        100.0 * h, 3.0 * tau, tau);
  if (c.has_normal) {
    out.explanation += Fmt(" The baseline residual follows normal stress (correlation %.2f) ", c.corr_normal) +
                       (std::fabs(c.corr_normal) >= std::fabs(c.corr_depth) ? "more than" : "less than") +
                       Fmt(" worn depth (%.2f).", c.corr_depth);
  }
}

void DescribeHardnessGradient(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  const double g = Param(f, e, 0), d0 = Param(f, e, 1), wrel = Param(f, e, 2);
  const double half = 0.5 * c.thickness_new_mm;
  const double onset = d0 * half, full = onset + std::max(wrel * (half - onset), 1.0);
  out.parameters["g"] = Round(g, 3);
  out.parameters["g_stderr"] = Round(ParamSe(f, e, 0), 3);
  out.parameters["onset_depth_mm"] = Round(onset, 1);
  out.parameters["onset_depth_mm_stderr"] = Round(ParamSe(f, e, 1) * half, 1);
  out.parameters["full_depth_mm"] = Round(full, 1);
  out.explanation = Fmt(
      "Wear accelerated once the surface reached about %.0f mm of worn depth, at every sensor alike, so the "
      "high-wear rows accelerated earlier in time: the wear rate is %.0f %% higher by %.0f mm depth. This is a "
      "%s (hardness falling with depth), not a change in time.",
      onset, 100.0 * g, full, full - onset < 0.25 * (half - onset) ? "softer layer under the surface" : "softer casting core");
  out.explanation += Fmt(" Baseline residual vs worn depth: correlation %.2f.", c.corr_depth);
}

void DescribeSqueezeWear(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  const double beta = Param(f, e, 0);
  out.parameters["beta"] = Round(beta, 3);
  out.parameters["beta_stderr"] = Round(ParamSe(f, e, 0), 3);
  out.explanation =
      Fmt("Extra wear where normal stress is high, in a fixed ratio from day 0: squeezing/compression wear that "
          "Finnie's angle law misses. Rate = k (I + %.2f n), n = normal stress in map-intensity units. The "
          "baseline residual follows normal stress (correlation %.2f), not depth (%.2f).",
          beta, c.corr_normal, c.corr_depth);
}

void DescribeProfileEvolution(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  const double p = Param(f, e, 0);
  out.parameters["form"] = "tilt";
  out.parameters["p_per_100_days"] = Round(p, 3);
  out.parameters["p_stderr"] = Round(ParamSe(f, e, 0), 3);
  out.parameters["top_vs_bottom_change_over_campaign"] = Round(p * c.span_days / 100.0, 3);
  out.explanation =
      Fmt("The relative wear rates along the concave drifted during the campaign: the rate at the top relative to "
          "the bottom changed by %+.0f %% over %.0f days, so the wear peak moved %%s as the chamber wore (the "
          "DEM of the new chamber cannot show this).",
          100.0 * p * c.span_days / 100.0, c.span_days);
  const size_t pos = out.explanation.find("moved %s");
  if (pos != std::string::npos) out.explanation.replace(pos, 8, p > 0 ? "moved up" : "moved down");
}

void DescribeProfileShift(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  const double v = Param(f, e, 0);
  const double height_m = c.height_m;
  out.parameters["form"] = "shift";
  out.parameters["shift_per_100_days"] = Round(v, 4);
  out.parameters["shift_stderr"] = Round(ParamSe(f, e, 0), 4);
  out.parameters["shift_over_campaign_m"] = Round(v * height_m * c.span_days / 100.0, 3);
  out.explanation =
      Fmt("The wear rates along the concave changed during the campaign the way the DEM's own wear profile "
          "would if it slid %s the liner: by about %.0f mm over %.0f days, with the same total wear. The "
          "worn chamber's geometry moves the crushing zone (the DEM of the new chamber cannot show this); "
          "rows change rate at the same time, not at the same worn depth.",
          v > 0 ? "up" : "down", 1000.0 * std::fabs(v) * height_m * c.span_days / 100.0, c.span_days);
}

void DescribeFeedSegregation(const ExplainContext& /*c*/, const FitResult& f, Effect e, Finding& out) {
  const double a = Param(f, e, 0), b = Param(f, e, 1);
  const double amp = std::hypot(a, b);
  double theta_f = std::atan2(b, a) * 180.0 / kPi;
  if (theta_f < 0) theta_f += 360.0;
  out.parameters["amplitude"] = Round(amp, 3);
  out.parameters["amplitude_stderr"] = Round(std::hypot(ParamSe(f, e, 0), ParamSe(f, e, 1)) / std::sqrt(2.0), 3);
  out.parameters["theta_f_deg"] = Round(theta_f, 1);
  out.explanation =
      Fmt("Wear varies around the circumference as 1 + %.2f cos(theta - %.0f deg), from day 0 and in a fixed ratio: "
          "one-sided feed (segregation) puts more coarse rock on the side at %.0f deg. The pattern follows the "
          "angle, not the segment joints.",
          amp, theta_f, theta_f);
}

void DescribeThroughputVariation(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  const double phi = Param(f, e, 0);
  out.parameters["phi"] = Round(phi, 3);
  out.parameters["phi_stderr"] = Round(ParamSe(f, e, 0), 3);
  out.parameters["throughput_variation_cv"] = Round(c.throughput_cv, 3);
  out.explanation =
      Fmt("All wear rates changed together with the tonnage log: %.0f %% of the wear rate follows throughput%%s "
          "rather than calendar time (throughput varied by %.0f %%).",
          100.0 * phi, 100.0 * c.throughput_cv);
  const size_t pos = out.explanation.find("throughput%s");
  if (pos != std::string::npos)
    out.explanation.replace(pos, 12, c.with_ai ? "throughput x abrasiveness (Bond: Ai + 0.22)" : "throughput");
}

}  // namespace

void DescribeEffect(const ExplainContext& c, const FitResult& f, Effect e, Finding& out) {
  switch (e) {
    case Effect::kWorkHardening:
      return DescribeWorkHardening(c, f, e, out);
    case Effect::kHardnessGradient:
      return DescribeHardnessGradient(c, f, e, out);
    case Effect::kSqueezeWear:
      return DescribeSqueezeWear(c, f, e, out);
    case Effect::kProfileEvolution:
      return DescribeProfileEvolution(c, f, e, out);
    case Effect::kProfileShift:
      return DescribeProfileShift(c, f, e, out);
    case Effect::kFeedSegregation:
      return DescribeFeedSegregation(c, f, e, out);
    case Effect::kThroughputVariation:
      return DescribeThroughputVariation(c, f, e, out);
  }
}

}  // namespace lw::diagnosis::detail
