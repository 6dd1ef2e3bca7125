// The campaign's truth: the wear integrated hour by hour on demand, the true thickness at each
// sensor and on each face, and the truth JSON (`linerwatch-sim campaign --truth`).
#include "sim/campaign.hpp"

#include <algorithm>
#include <cmath>

#include "campaign_model.hpp"

namespace lw::sim {
using namespace model;

void Campaign::Integrate(double to_day) const {
  const CampaignSpec& s = spec_;
  const long target = static_cast<long>(std::ceil(to_day * 24.0));
  if (target <= hours_done_) return;
  const EffectSpec* hard = Find(s.effects, "work_hardening");
  const EffectSpec* grad = Find(s.effects, "hardness_gradient");
  const EffectSpec* squeeze = Find(s.effects, "squeeze_wear");
  const EffectSpec* profile = Find(s.effects, "profile_evolution");
  const EffectSpec* feed = Find(s.effects, "feed_segregation");
  const EffectSpec* loss = Find(s.effects, "material_loss");
  const auto ns = sensor_now_.size();
  const double dt = 1.0 / 24.0;

  auto ProfileShift = [&](double day) { return profile ? Param(*profile, "p", 0.6) * 0.15 * day / s.reference_day : 0.0; };
  double profile_norm = 1.0;
  auto rate = [&](double zeta, double theta, double normal, double d, double day, double q) {
    double w = Abrasion(zeta);
    if (profile) {
      // The worn chamber nips rock higher up: the wear profile slides up the liner. The same
      // tonnage does the same total work, so the shifted profile keeps the liner-mean intensity.
      w = Abrasion(zeta - ProfileShift(day)) * profile_norm;
    }
    double m = 1.0;
    if (hard) {
      const double h = Param(*hard, "h", 0.4), tau = Param(*hard, "tau_days", 6);
      m *= 1.0 - h * std::pow(normal, 1.5) * std::tanh(day / tau);
    }
    if (grad) {
      const double cc = Param(*grad, "c", 0.2), d0 = Param(*grad, "onset_mm", 25), wd = Param(*grad, "width_mm", 30);
      m /= 1.0 - cc * SmoothStep((d - d0) / wd);
    }
    if (feed) {
      const double A = Param(*feed, "amplitude", 0.15), tf = Param(*feed, "theta_deg", 0);
      m *= 1.0 + A * std::cos((theta - tf) * kDeg) * (0.6 + 0.4 * (1.0 - zeta));
    }
    double extra = 0;
    if (squeeze) extra = Param(*squeeze, "beta", 0.2) * 0.5 * std::pow(normal, 1.2);
    return k_mm_per_day_ * q * (w * m + extra);
  };

  for (long h = hours_done_; h < target; ++h) {
    const double day = static_cast<double>(h) / 24.0;
    const double q = static_cast<size_t>(h) < throughput_q_.size() ? throughput_q_[static_cast<size_t>(h)] : 1.0;
    if (profile) {
      double a0 = 0, a1 = 0;
      for (int i = 0; i < 60; ++i) {
        const double zeta = (i + 0.5) / 60.0;
        a0 += Abrasion(zeta);
        a1 += Abrasion(zeta - ProfileShift(day));
      }
      profile_norm = a0 / a1;
    }
    for (Eigen::Index i = 0; i < face_now_.size(); ++i) {
      face_now_[i] += dt * rate(map_.z[i] / s.height_m, map_.theta_deg[i], normal_[i], face_now_[i], day, q);
    }
    for (Eigen::Index k = 0; k < ns; ++k) {
      sensor_now_[k] += dt * rate(sensor_z_[k] / s.height_m, sensor_theta_[k], sensor_normal_[k], sensor_now_[k], day, q);
    }
    if (loss) {
      const double t0 = Param(*loss, "day", 40);
      if (day <= t0 && day + dt > t0) {
        const auto si = static_cast<Eigen::Index>(Param(*loss, "sensor_index", 6));
        const double z0 = Param(*loss, "z_m", si < ns ? sensor_z_[si] : 0.5);
        const double th0 = Param(*loss, "theta_deg", si < ns ? sensor_theta_[si] : 0);
        const double depth = Param(*loss, "depth_mm", 10), sigma = Param(*loss, "radius_m", 0.1);
        const double r0 = s.r_bottom_m + (s.r_top_m - s.r_bottom_m) * z0 / s.height_m;
        auto crater = [&](double z, double th) {
          double dth = std::fmod(th - th0 + 540.0, 360.0) - 180.0;
          const double arc = r0 * dth * kDeg;
          return depth * std::exp(-((z - z0) * (z - z0) + arc * arc) / (2 * sigma * sigma));
        };
        for (Eigen::Index i = 0; i < face_now_.size(); ++i) face_now_[i] += crater(map_.z[i], map_.theta_deg[i]);
        for (Eigen::Index k = 0; k < ns; ++k) sensor_now_[k] += crater(sensor_z_[k], sensor_theta_[k]);
      }
    }
    for (Eigen::Index k = 0; k < ns; ++k) sensor_hourly_flat_.push_back(sensor_now_[k]);
    if ((h + 1) % 24 == 0) face_daily_.push_back(face_now_);
  }
  hours_done_ = target;
}

double Campaign::TrueSensorThickness(size_t index, double day) const {
  Integrate(day + 1.0 / 24.0);
  const auto ns = static_cast<size_t>(sensor_now_.size());
  const double hf = std::max(0.0, day * 24.0);
  const auto h0 = static_cast<size_t>(hf);
  const double f = hf - static_cast<double>(h0);
  const double w0 = sensor_hourly_flat_[h0 * ns + index];
  const double w1 = (h0 + 1) * ns + index < sensor_hourly_flat_.size() ? sensor_hourly_flat_[(h0 + 1) * ns + index] : w0;
  return spec_.thickness_new_mm - (w0 + f * (w1 - w0));
}

Eigen::VectorXd Campaign::TrueFaceWear(double day) const {
  Integrate(std::ceil(day) + 1.0);
  const auto d0 = static_cast<size_t>(std::max(0.0, std::floor(day)));
  const double f = day - static_cast<double>(d0);
  if (d0 + 1 >= face_daily_.size()) return face_daily_.back();
  return face_daily_[d0] + f * (face_daily_[d0 + 1] - face_daily_[d0]);
}

nlohmann::json Campaign::TruthJson() const {
  nlohmann::json j;
  j["seed"] = seed_;
  j["spec"] = spec_.ToJson();
  j["k_mm_per_day"] = k_mm_per_day_;
  j["sensors"] = nlohmann::json::object();
  for (size_t k = 0; k < crusher_.sensors.size(); ++k) {
    nlohmann::json series = nlohmann::json::array();
    for (int d = 0; d <= static_cast<int>(spec_.days); ++d) series.push_back(TrueSensorThickness(k, d));
    j["sensors"][crusher_.sensors[k].id] = {{"true_thickness_mm_daily", series}};
  }
  return j;
}

}  // namespace lw::sim
