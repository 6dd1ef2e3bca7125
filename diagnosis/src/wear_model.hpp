#pragma once
/// The wear model: dw/dt = k_row(z) * (I + beta n_I) * product of effect multipliers, integrated in
/// time on a uniform grid. Each effect is a parameterised, physically meaningful change of the DEM
/// assumption "wear rate proportional to the map intensity, constant in time".
#include <Eigen/Core>
#include <string>
#include <vector>

namespace lw::diagnosis::detail {

enum class Effect : int {
  kWorkHardening = 0,
  kHardnessGradient,
  kSqueezeWear,
  kProfileEvolution,
  kFeedSegregation,
  kThroughputVariation,
  kProfileShift,  ///< profile_evolution, second form: the DEM's own z-profile translating along the liner
};
inline constexpr int kEffectCount = 7;
/// Contract name of the effect (both profile forms are "profile_evolution").
const char* EffectName(Effect effect);
/// Name of the effect's form in the list of hypotheses ("profile_evolution:shift").
const char* FormName(Effect effect);

struct ParamSpec {
  std::string name;
  double lower = 0;
  double upper = 0;
  double initial = 0;
  double scale = 1;  ///< typical magnitude, for numeric derivatives
  /// A shape parameter (work hardening's time constant, the hardness gradient's onset depth): it
  /// exists only when the effect's size is not zero, so it is not identified at zero size.
  bool shape = false;
};
std::vector<ParamSpec> EffectParams(Effect effect);

/// One place where wear is modelled (a sensor or a scan cell).
struct ModelPoint {
  double intensity = 0;     ///< normalised DEM intensity
  double normal_tilde = 1;  ///< normal stress / robust max (1 when the map has none)
  double normal_i = 0;      ///< normal stress in intensity units (squeeze wear)
  double broad_i = 0;       ///< the map smoothed like the stress, same units (squeeze wear's stand-in without stress)
  double zn = 0;            ///< (z - z_mid) / concave height, about [-0.5, 0.5]
  double shift_rel = 0;     ///< relative rate change per concave height of upward profile shift (total kept)
  double cos_t = 1;
  double sin_t = 0;
  double half_thickness_mm = 50;
  int row_a = 0;  ///< k = weight_a * k[row_a] + (1 - weight_a) * k[row_b]
  int row_b = 0;
  double weight_a = 1;
};

struct ModelSpec {
  std::vector<Effect> effects;
  size_t rows = 1;
  size_t ParamCount() const;
  /// Index of the effect's first parameter in the vector, or -1 when the effect is not in the model.
  int Offset(Effect effect) const;
  bool Has(Effect effect) const { return Offset(effect) >= 0; }
  std::string Name() const;
  void Bounds(Eigen::VectorXd& lower, Eigen::VectorXd& upper, Eigen::VectorXd& scale, Eigen::VectorXd& initial,
              double k_scale) const;
};

struct TimeGrid {
  double dt = 1;
  size_t steps = 1;
  std::vector<double> throughput;  ///< per step, throughput x abrasiveness / its mean; 1 when unknown
};

/// Wear (mm) of every point at every grid time: rows = points, cols = steps + 1.
void Simulate(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points, const TimeGrid& grid,
              Eigen::MatrixXd& wear);
/// Wear of every point at one time (no history kept; for the whole mesh).
Eigen::VectorXd SimulateAt(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points,
                           const TimeGrid& grid, double t_days);

/// Whether `spec` makes the wear rate depend on the depth already worn (the hardness gradient).
/// Then a point whose intensity is off by a factor 1 + u (a sensor's intensity error) does not wear
/// along the same curve scaled by 1 + u: it reaches the onset earlier or later.
bool DepthDependent(const ModelSpec& spec);

/// The point with its rate scaled by `factor` (intensity and normal stress): a sensor with
/// intensity error u (factor 1 + u) simulated on its own depth curve.
ModelPoint ScaledRate(ModelPoint point, double factor);

/// The rate factor of a sensor with intensity error u on its own depth curve: 1 + u, at least 0.05.
double OwnRateFactor(double u);

/// For a depth-dependent spec: the wear of each point simulated at its rate times factors[i] and
/// divided by factors[i] again (so that wear * factors[i] is the point's wear on its own depth
/// curve), at every step of `grid` (`wear`, points x steps + 1). Otherwise the plain simulation.
void SimulateOwnRates(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points,
                      const std::vector<double>& factors, const TimeGrid& grid, Eigen::MatrixXd& wear);
/// The same at one time (SimulateAt).
Eigen::VectorXd SimulateOwnRatesAt(const ModelSpec& spec, const Eigen::VectorXd& params, const std::vector<ModelPoint>& points,
                                   const std::vector<double>& factors, const TimeGrid& grid, double t_days);

}  // namespace lw::diagnosis::detail
