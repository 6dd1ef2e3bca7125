#include "synthetic_bundle.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <vector>

namespace lw::test {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kHeight = 2.0;
constexpr double kThickness = 100.0;
constexpr int kNz = 20;
constexpr int kNt = 48;

double Radius(double z) {
  return 1.0 + 0.4 * z;
}
double TrueIntensity(double z, double theta) {
  return (0.25 + 1.75 * std::exp(-z / 0.7)) * (1.0 + 0.08 * std::cos(3.0 * theta) + 0.05 * std::sin(5.0 * theta));
}
double TrueNormal(double z, double theta) {
  return 0.3 + std::exp(-std::pow((z - 0.9) / 0.45, 2)) * (1.0 + 0.4 * std::sin(2.0 * theta + 0.5));
}
constexpr double kNormalMax = 1.7;  // about the field's maximum

double Throughput(double t) {
  if (t >= 30 && t < 36) return 0.05;
  return 1.0 + 0.35 * std::sin(2 * kPi * t / 23.0);
}

std::string Iso(double days) {
  const auto base = std::chrono::sys_days{std::chrono::year{2024} / 1 / 1};
  const auto t = std::chrono::time_point_cast<std::chrono::seconds>(base) +
                 std::chrono::seconds(static_cast<long long>(std::llround(days * 86400.0)));
  const auto d = std::chrono::floor<std::chrono::days>(t);
  const std::chrono::year_month_day ymd{d};
  const std::chrono::hh_mm_ss hms{t - d};
  char b[40];
  std::snprintf(b, sizeof b, "%04d-%02u-%02uT%02lld:%02lld:%02lldZ", static_cast<int>(ymd.year()),
                static_cast<unsigned>(ymd.month()), static_cast<unsigned>(ymd.day()), static_cast<long long>(hms.hours().count()),
                static_cast<long long>(hms.minutes().count()), static_cast<long long>(hms.seconds().count()));
  return b;
}

struct Truth {
  const SyntheticSpec& s;
  double q_mean = 1;
  explicit Truth(const SyntheticSpec& spec) : s(spec) {
    double sum = 0;
    int n = 0;
    for (double t = 0.05; t < s.days; t += 0.1) {
      sum += Throughput(t);
      ++n;
    }
    q_mean = sum / n;
  }
  // The spall's (or smooth dip's) depth at (z, theta) after `days` (theta in radians).
  double Crater(double z, double theta, double days) const {
    if (s.crater_mm <= 0 || days < s.crater_day) return 0;
    const double dth = std::remainder(theta - s.crater_theta_deg * kPi / 180.0, 2 * kPi);
    const double r = std::hypot(z - s.crater_z, dth * Radius(s.crater_z));
    const double a = s.crater_radius_m;
    if (s.crater_smooth) {
      // Same volume as the disc: depth x pi a^2 = peak x 2 pi a^2.
      return 0.5 * s.crater_mm * std::exp(-r * r / (2 * a * a));
    }
    return s.crater_mm * std::clamp((a + 0.005 - r) / 0.01, 0.0, 1.0);
  }
  // Wear (mm) at (z, theta) after `days`.
  double Wear(double z, double theta, double days) const { return BaseWear(z, theta, days) + Crater(z, theta, days); }
  double BaseWear(double z, double theta, double days) const {
    const double intensity = TrueIntensity(z, theta);
    const double nt = TrueNormal(z, theta) / kNormalMax;
    const double n_i = TrueNormal(z, theta);  // in intensity units (both fields average near 1)
    const double zn = (z - kHeight / 2) / kHeight;
    double base = s.rate * (intensity + s.squeeze_beta * n_i);
    base *= 1.0 + s.feed_amplitude * std::cos(theta - s.feed_theta_deg * kPi / 180.0);
    const double dt = 0.05;
    double w = 0;
    for (double t = 0; t < days - 1e-12; t += dt) {
      const double step = std::min(dt, days - t);
      const double tm = t + 0.5 * step;
      double f = base;
      if (s.hardening_h > 0) f *= 1.0 - s.hardening_h * nt * (1.0 - std::exp(-tm / s.hardening_tau_days));
      if (s.profile_p != 0) f *= std::max(0.05, 1.0 + s.profile_p * zn * tm / 100.0);
      if (s.throughput_phi > 0) f *= 1.0 + s.throughput_phi * (Throughput(tm) / q_mean - 1.0);
      if (s.gradient_g > 0) {
        const double width = s.gradient_width_mm > 0 ? s.gradient_width_mm : kThickness / 2 - s.gradient_onset_mm;
        const double x = std::clamp((w - s.gradient_onset_mm) / width, 0.0, 1.0);
        f *= 1.0 + s.gradient_g * x;
      }
      w += step * f;
    }
    return w;
  }
};

}  // namespace

void WriteSyntheticBundle(const std::filesystem::path& dir, const SyntheticSpec& s) {
  std::filesystem::create_directories(dir);
  std::mt19937 rng(s.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Truth truth(s);

  // Rows and sensors.
  const std::array<const char*, 3> rows = {"LDWN", "LMID", "LUP"};
  struct Sensor {
    std::string id, row;
    double z, theta_deg;
  };
  std::vector<Sensor> sensors;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 4; ++k) {
      sensors.push_back({std::string(rows[static_cast<size_t>(r)]) + "-" + std::to_string(k + 1), rows[static_cast<size_t>(r)],
                         (r + 0.5) * kHeight / 3.0, 22.5 + 90.0 * k});
    }
  }
  {
    std::ofstream c(dir / "crusher.json");
    c << "{\"crusher_id\": \"synthetic\", \"installed_at\": \"2024-01-01T00:00:00Z\", \"concave\": "
         "{\"thickness_new_mm\": 100, \"thickness_min_mm\": 20, \"rows\": [";
    for (int r = 0; r < 3; ++r) {
      c << (r ? ", " : "") << "{\"name\": \"" << rows[static_cast<size_t>(r)] << "\", \"z_min_m\": " << r * kHeight / 3.0
        << ", \"z_max_m\": " << (r + 1) * kHeight / 3.0 << "}";
    }
    c << "]}, \"sensors\": [";
    for (size_t i = 0; i < sensors.size(); ++i) {
      c << (i ? ", " : "") << "{\"id\": \"" << sensors[i].id << "\", \"row\": \"" << sensors[i].row
        << "\", \"z_m\": " << sensors[i].z << ", \"theta_deg\": " << sensors[i].theta_deg << ", \"thickness_new_mm\": 100}";
    }
    c << "]}\n";
  }

  // Map: a cone, (kNz x kNt) quads split in triangles.
  std::vector<std::array<double, 3>> pts;
  for (int iz = 0; iz <= kNz; ++iz) {
    for (int it = 0; it < kNt; ++it) {
      const double z = kHeight * iz / kNz, th = 2 * kPi * it / kNt;
      pts.push_back({Radius(z) * std::cos(th), Radius(z) * std::sin(th), z});
    }
  }
  std::vector<std::array<int, 3>> faces;
  for (int iz = 0; iz < kNz; ++iz) {
    for (int it = 0; it < kNt; ++it) {
      const int a = iz * kNt + it, b = iz * kNt + (it + 1) % kNt, c = (iz + 1) * kNt + it, d = (iz + 1) * kNt + (it + 1) % kNt;
      faces.push_back({a, b, d});
      faces.push_back({a, d, c});
    }
  }
  auto centroid = [&](const std::array<int, 3>& f) {
    std::array<double, 3> c{0, 0, 0};
    for (int v : f)
      for (int k = 0; k < 3; ++k) c[static_cast<size_t>(k)] += pts[static_cast<size_t>(v)][static_cast<size_t>(k)] / 3.0;
    return c;
  };
  {
    // Per-face values first (same random stream whatever the format).
    std::uniform_real_distribution<double> hit(0.0, 1.0);
    std::vector<double> wear_raw, normal_raw;
    for (const auto& f : faces) {
      const auto c = centroid(f);
      const double th = std::atan2(c[1], c[0]);
      const double smooth = (1.0 + s.map_smooth_error * std::sin(3.0 * c[2] + 0.5) * std::cos(2.0 * th + 1.0)) *
                            (1.0 + s.map_profile_error * std::sin(7.0 * c[2] + 0.7));
      double v = TrueIntensity(c[2], th) * smooth * std::max(0.05, 1.0 + s.map_noise * gauss(rng)) * s.map_scale;
      if (s.map_zero_fraction > 0 && hit(rng) < s.map_zero_fraction) v = 0;
      wear_raw.push_back(v);
    }
    if (s.with_normal_stress) {
      for (const auto& f : faces) {
        const auto c = centroid(f);
        normal_raw.push_back(TrueNormal(c[2], std::atan2(c[1], c[0])) * std::max(0.05, 1.0 + s.map_noise * gauss(rng)) * 1.0e5);
      }
    }
    auto wear_text = [&](double v) {
      char b[48];
      std::snprintf(b, sizeof b, s.map_printf_f ? "%f" : "%.6g", v);
      return std::string(b);
    };
    std::ofstream m(dir / "wear_map.vtk");
    if (s.map_format == "liggghts") {
      m << "# vtk DataFile Version 5.1\nGenerated by LIGGGHTS\nASCII\nDATASET POLYDATA\nPOINTS " << 3 * faces.size()
        << " float\n";
      for (const auto& f : faces) {
        for (int v : f) {
          const auto& p = pts[static_cast<size_t>(v)];
          m << p[0] << " " << p[1] << " " << p[2] << " ";
        }
        m << "\n";
      }
      m << "\nPOLYGONS " << faces.size() + 1 << " " << 3 * faces.size() << "\nOFFSETS vtktypeint64\n";
      for (size_t k = 0; k <= faces.size(); ++k) m << 3 * k << " ";
      m << "\nCONNECTIVITY vtktypeint64\n";
      for (size_t k = 0; k < 3 * faces.size(); ++k) m << k << " ";
      m << "\nCELL_DATA " << faces.size() << "\nFIELD FieldData " << (s.with_normal_stress ? 3 : 1) << "\n";
      if (s.with_normal_stress) {
        m << "normal_stress_average 1 " << faces.size() << " double\n";
        for (double v : normal_raw) m << v << " ";
        m << "\nshear_stress_average 1 " << faces.size() << " double\n";
        for (double v : normal_raw) m << 0.3 * v << " ";
        m << "\n";
      }
      m << "wear 1 " << faces.size() << " double\n";
      for (double v : wear_raw) m << wear_text(v) << " ";
      m << "\n";
    } else {
      m << "# vtk DataFile Version 4.2\nsynthetic concave\nASCII\nDATASET POLYDATA\nPOINTS " << pts.size() << " double\n";
      for (const auto& p : pts) m << p[0] << " " << p[1] << " " << p[2] << "\n";
      m << "POLYGONS " << faces.size() << " " << faces.size() * 4 << "\n";
      for (const auto& f : faces) m << "3 " << f[0] << " " << f[1] << " " << f[2] << "\n";
      m << "CELL_DATA " << faces.size() << "\nSCALARS wear double 1\nLOOKUP_TABLE default\n";
      for (double v : wear_raw) m << wear_text(v) << "\n";
      if (s.with_normal_stress) {
        m << "SCALARS normal_stress_average double 1\nLOOKUP_TABLE default\n";
        for (double v : normal_raw) m << v << "\n";
      }
    }
  }

  // Readings.
  {
    std::ofstream r(dir / "readings.csv");
    r << "time,sensor_id,thickness_mm\n";
    const double step = s.report_hours / 24.0;
    for (const Sensor& sn : sensors) {
      const double th = sn.theta_deg * kPi / 180.0;
      double stuck_value = -1;
      // Tabulate the truth on a coarse grid, interpolate (speed).
      std::vector<double> tab;
      for (double t = 0; t <= s.days + 1; t += 0.5) tab.push_back(truth.Wear(sn.z, th, t));
      auto wear_at = [&](double t) {
        const double x = t / 0.5;
        const auto j = static_cast<size_t>(x);
        const double f = x - static_cast<double>(j);
        return j + 1 < tab.size() ? tab[j] * (1 - f) + tab[j + 1] * f : tab.back();
      };
      for (double t = step; t <= s.days + 1e-9; t += step) {
        double w = wear_at(t);
        if (sn.id == s.loss_sensor && t >= s.loss_day) w += s.loss_mm;
        double value = std::max(0.0, std::floor(kThickness - w));
        if (sn.id == s.stuck_sensor && t >= s.stuck_from_day) {
          if (stuck_value < 0) stuck_value = value;
          value = stuck_value;
        }
        r << Iso(t) << "," << sn.id << "," << value << "\n";
      }
    }
  }

  if (s.with_operations) {
    std::ofstream o(dir / "operations.csv");
    o << "time,throughput_tph\n";
    for (double t = 0; t <= s.days; t += 1.0) o << Iso(t) << "," << 3500.0 * Throughput(t + 0.5) << "\n";
  }

  if (s.with_scan) {
    std::filesystem::create_directories(dir / "scans");
    const double scan_day = s.scan_day > 0 ? s.scan_day : s.days;
    std::ofstream sc(dir / "scans" / ("scan_" + Iso(scan_day).substr(0, 10) + ".xyz"));
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    for (const auto& f : faces) {
      for (int k = 0; k < 6; ++k) {
        double a = uni(rng), b = uni(rng);
        if (a + b > 1) {
          a = 1 - a;
          b = 1 - b;
        }
        std::array<double, 3> p{};
        for (int d = 0; d < 3; ++d) {
          const auto dd = static_cast<size_t>(d);
          p[dd] = pts[static_cast<size_t>(f[0])][dd] +
                  a * (pts[static_cast<size_t>(f[1])][dd] - pts[static_cast<size_t>(f[0])][dd]) +
                  b * (pts[static_cast<size_t>(f[2])][dd] - pts[static_cast<size_t>(f[0])][dd]);
        }
        const double th = std::atan2(p[1], p[0]);
        double w = truth.Wear(p[2], th, scan_day) + s.scan_noise_mm * gauss(rng);
        // Move outward, perpendicular to the cone surface (normal of r = 1 + 0.4 z).
        const double nr = 1.0 / std::sqrt(1.0 + 0.16), nz = -0.4 / std::sqrt(1.0 + 0.16);
        p[0] += std::cos(th) * nr * w / 1000.0;
        p[1] += std::sin(th) * nr * w / 1000.0;
        p[2] += nz * w / 1000.0;
        sc << p[0] << " " << p[1] << " " << p[2] << "\n";
      }
    }
  }
}

}  // namespace lw::test
