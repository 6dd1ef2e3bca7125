#pragma once
/// The findings' explanations: each effect's fitted parameters in physical units and the sentence
/// that says what the liner did (docs/diagnosis.md, "Reading the report").
#include "diagnosis/diagnose.hpp"
#include "model_fit.hpp"

namespace lw::diagnosis::detail {

/// What the explanations need beyond the fit.
struct ExplainContext {
  bool has_normal = false;      ///< the map has normal stress
  double height_m = 0;          ///< mapped liner height (z_top - z_bottom)
  double thickness_new_mm = 0;  ///< the crusher's as-new liner thickness
  double span_days = 0;         ///< latest observation, days since installation
  double throughput_cv = 0;     ///< variation of the throughput series
  bool with_ai = false;         ///< operations.csv carries ore abrasiveness
  double corr_normal = 0;       ///< correlation of the baseline's relative residual with normal stress
  double corr_depth = 0;        ///< ... and with worn depth
};

/// Fills out.parameters and out.explanation for effect `e` of fit `f`.
void DescribeEffect(const ExplainContext& c, const FitResult& f, Effect e, Finding& out);

}  // namespace lw::diagnosis::detail
