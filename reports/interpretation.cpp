#include "reports/interpretation.h"

#include "core/bands.h"
#include "reports/writers.h"

#include <cmath>
#include <cstdio>

namespace ms::reports {
namespace {

std::string signed_num(double v, int prec) {
  if (!std::isfinite(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%+.*f", prec, v);
  return b;
}

const char* side_of(double signed_mm) { return signed_mm > 0 ? "towards the left" : "towards the right"; }

// A left-right difference shown with its meaning but without a band.
Interpretation unbanded_difference(const std::string& key, const std::string& title, double left, double right, int prec,
                                   const std::string& unit, const std::string& between, const std::string& missing,
                                   const std::string& meaning, const std::string& thresholds) {
  Interpretation x;
  x.key = key;
  x.title = title;
  const double diff = left - right;
  const bool ok = std::isfinite(diff);
  x.value_text = ok ? signed_num(diff, prec) + unit : "n/a";
  x.detail = ok ? "L " + fixed(left, 1) + unit + ", R " + fixed(right, 1) + unit + " (" + between + ")" : missing;
  x.banded_value = ok ? std::abs(diff) : kNaN;
  x.band = ok ? Band::Unbanded : Band::Unavailable;
  x.meaning = meaning;
  x.thresholds = thresholds;
  return x;
}

}  // namespace

const char* band_label(Band b) { return band_label_of(band_name(b)).data(); }

const char* band_name(Band b) {
  switch (b) {
    case Band::Typical: return "typical";
    case Band::Mild: return "mild";
    case Band::Marked: return "marked";
    case Band::Unbanded: return "unbanded";
    case Band::Unavailable: return "unavailable";
  }
  return "";
}

Band classify(double value, const Thresholds& t) {
  if (!std::isfinite(value)) return Band::Unavailable;
  if (value >= t.marked) return Band::Marked;
  if (value >= t.mild) return Band::Mild;
  return Band::Typical;
}

double habets_index_pct(double left, double right) {
  if (!std::isfinite(left) || !std::isfinite(right) || left + right <= 0) return kNaN;
  return 100.0 * std::abs(left - right) / (left + right);
}

const std::vector<Reference>& interpretation_references() {
  static const std::vector<Reference> refs = {
      {"masuoka2007",
       "Masuoka N, Muramatsu A, Ariji Y, Nawa H, Goto S, Ariji E. Discriminative thresholds of cephalometric indexes "
       "in the subjective evaluation of facial asymmetry. Am J Orthod Dentofacial Orthop 2007;131(5):609-613. "
       "(Orthodontists' thresholds for treatment need: menton deviation, mean 4.28 mm.)"},
      {"nur2016",
       "Nur RB, Germe\xC3\xA7 \xC3\x87" "akan D, Arun T. Evaluation of facial hard and soft tissue asymmetry using "
       "cone-beam computed tomography. Am J Orthod Dentofacial Orthop 2016;149(2):225-237. (Asymmetric group: "
       "menton deviation of 4 mm or more.)"},
      {"thai_chin",
       "The differences of perception of asymmetry on chin and lip in facial asymmetry patients rated by laypersons "
       "and orthodontists. Thai J Orthod (he01.tci-thaijo.org, article 276937). (Chin deviation 0-2 mm rated normal; "
       "over 2-4 mm unacceptable to orthodontists; over 4 mm unacceptable to both groups.)"},
      {"habets1988",
       "Habets LLMH, Bezuur JN, Naeiji M, Hansson TL. The orthopantomogram, an aid in diagnosis of temporomandibular "
       "joint problems. II. The vertical symmetry. J Oral Rehabil 1988;15(5):465-471. (Condylar and ramus asymmetry "
       "index 100|R-L|/(R+L); above 3 % counted as asymmetric.)"},
      {"pintowong2024",
       "Pinto-Wong S, et al. Prevalence of mandibular, condylar and ramus asymmetry in panoramic radiographs of adult "
       "individuals. J Clin Exp Dent 2024;16(11):e1332-e1338. (Applies Habets' index with the 3 % criterion.)"},
      {"cevidanes2011",
       "Cevidanes LHS, Alhadidi A, Paniagua B, Styner M, Ludlow J, Mol A, Turvey T, Proffit WR, Rossouw PE. 3D "
       "quantification of mandibular asymmetry through cone beam computed tomography. Oral Surg Oral Med Oral Pathol "
       "Oral Radiol Endod 2011;111(6):757-770. (Mirror surface distance; differences from simulated asymmetry below "
       "0.5 mm.)"},
      {"choi2015",
       "Choi KY. Analysis of facial asymmetry. Arch Craniofac Surg 2015;16(1):1-10. (Differences below 3-4 mm and "
       "canting below 3-4\xC2\xB0 are generally not recognised as asymmetry.)"},
      {"mandisym_phantoms",
       "MandiSym docs/method.md, \"What the SAF score separates\": SAF score of graded phantoms at four poses "
       "(ground-truth masks: symmetric 0.004-0.015 rad; ramus +2 mm 0.011-0.020; ramus +4 mm 0.022-0.030; body and "
       "chin +2 mm 0.024 and above; through mandisym run, 0.5-1 mm, with occlusion or metal: symmetric "
       "0.002-0.007, ramus +2 mm 0.010-0.015, ramus +4 mm 0.021-0.023). Not clinical data."},
  };
  return refs;
}

namespace {

// SAF score: the project's own metric; band from phantoms only.
Interpretation saf_interpretation(const InterpretationInputs& in) {
  Interpretation x;
  x.key = "saf_score";
  x.title = "SAF asymmetry score";
  x.value_text = std::isfinite(in.saf_score) ? fixed(in.saf_score, 3) + " rad" : "n/a";
  x.banded_value = in.saf_score;
  x.band = classify(in.saf_score, kSafThresholds);
  x.meaning =
      "How much the shape of one side differs from the mirror image of the other, compared through harmonic-field "
      "angles (0 = perfect symmetry). MandiSym's own metric: there is no published threshold.";
  x.thresholds = "below " + fixed(kSafThresholds.mild, 3) + " typical (all symmetric phantoms); " +
                 fixed(kSafThresholds.mild, 3) + "-" + fixed(kSafThresholds.marked, 3) +
                 " mild (like a 2 mm ramus elongation); " + fixed(kSafThresholds.marked, 3) +
                 " and above marked (like a 4 mm ramus or 2 mm body/chin change). Provisional, phantom-derived, "
                 "not clinically validated.";
  x.sources = {"mandisym_phantoms"};
  x.provisional = true;
  return x;
}

// Mirror distance: band on p95 of |d|.
Interpretation mirror_interpretation(const InterpretationInputs& in) {
  Interpretation x;
  x.key = "mirror_distance";
  x.title = "Mirror distance RMS / p95";
  x.value_text = fixed(in.mirror_rms_mm, 2) + " / " + fixed(in.mirror_p95_mm, 2) + " mm";
  x.banded_value = in.mirror_p95_mm;
  x.band = classify(in.mirror_p95_mm, kMirrorP95Thresholds);
  x.detail = "band from the p95; RMS is shown for comparison between scans";
  x.meaning =
      "Distance between the surface and its reflection through the symmetry plane (Cevidanes et al. 2011): RMS "
      "over the whole mandible, and the 95th percentile, i.e. what the most asymmetric 5 % of the surface exceeds.";
  x.thresholds =
      "p95 below 2 mm typical; 2-4 mm mild; 4 mm and above marked. 2 mm is the usual clinical-relevance "
      "convention of CBCT surface-distance maps and 4 mm the size of asymmetry that is generally recognised; "
      "neither is a validated cut-off for this statistic.";
  x.sources = {"cevidanes2011", "choi2015"};
  x.provisional = true;
  return x;
}

// Ramus height: Habets' index.
Interpretation ramus_interpretation(const InterpretationInputs& in) {
  Interpretation x;
  x.key = "ramus_height";
  x.title = "Ramus height L\xE2\x88\x92R";
  const double diff = in.ramus_L_mm - in.ramus_R_mm;
  const double idx = habets_index_pct(in.ramus_L_mm, in.ramus_R_mm);
  x.value_text = std::isfinite(diff) ? signed_num(diff, 2) + " mm" : "n/a";
  x.detail = std::isfinite(diff) ? "L " + fixed(in.ramus_L_mm, 1) + ", R " + fixed(in.ramus_R_mm, 1) +
                                       " mm (Co\xE2\x80\x93Go); asymmetry index " + fixed(idx, 1) + " %"
                                 : "Co or Go missing on a side";
  x.banded_value = idx;
  x.band = classify(idx, kRamusIndexThresholds);
  x.meaning =
      "Difference in ramus height (condylion to gonion) between the sides, banded by Habets' asymmetry index "
      "100|L\xE2\x88\x92R|/(L+R).";
  x.thresholds =
      "index below 3 % typical (Habets' criterion); 3-6 % mild; 6 % and above marked (twice Habets' cut-off: "
      "a MandiSym convention, not published). Habets measured on panoramic radiographs, not on 3D landmarks.";
  x.sources = {"habets1988", "pintowong2024"};
  return x;
}

// Menton deviation: from the cranial mid-sagittal plane when there is one.
Interpretation menton_interpretation(const InterpretationInputs& in) {
  Interpretation x;
  x.key = "menton_deviation";
  const double d = in.menton_to_plane_mm;
  x.value_text = std::isfinite(d) ? fixed(std::abs(d), 2) + " mm" : "n/a";
  x.banded_value = std::isfinite(d) ? std::abs(d) : kNaN;
  x.band = classify(x.banded_value, kMentonThresholds);
  x.measured_from = in.menton_plane_cranial ? "cranial_plane" : "mandible_plane";
  if (in.menton_plane_cranial) {
    x.title = "Menton deviation from the cranial midline";
    x.detail = std::isfinite(d) ? std::string(side_of(d)) + " of the cranial mid-sagittal plane" +
                                      (std::isfinite(in.menton_to_mandible_plane_mm)
                                           ? "; " + fixed(std::abs(in.menton_to_mandible_plane_mm), 2) +
                                                 " mm from the mandible's own plane"
                                           : std::string())
                                : "menton not found";
    x.meaning =
        "Lateral distance of menton (lowest point of the chin) from the mirror plane of the skull above the "
        "condyles: the chin's total deviation, as the cited studies measure it against the facial midline. The "
        "mandible's own plane leans with a deformed mandible and would understate it.";
  } else {
    x.title = "Menton deviation from the plane";
    x.detail = std::isfinite(d) ? std::string(side_of(d)) + " of the mandible's symmetry plane" : "menton not found";
    x.meaning =
        "Lateral distance of menton (lowest point of the chin) from the symmetry plane. The plane is fitted to the "
        "mandible itself (the scan holds too little skull for a cranial plane), not to the cranial base or face as "
        "in the cited studies, so this underestimates a chin deviation that the whole mandible shares.";
  }
  x.thresholds =
      "below 2 mm typical; 2-4 mm mild (noticed by orthodontists); 4 mm and above marked (the threshold at which "
      "orthodontists judge treatment needed, mean 4.28 mm, and the usual definition of an asymmetric group).";
  x.sources = {"masuoka2007", "nur2016", "thai_chin"};
  return x;
}

}  // namespace

// The four banded numbers, then two shown without a band, in display order.
std::vector<Interpretation> interpret(const InterpretationInputs& in) {
  std::vector<Interpretation> out = {saf_interpretation(in), mirror_interpretation(in), ramus_interpretation(in),
                                     menton_interpretation(in)};
  // No published cut-off found for these two: shown, not banded.
  out.push_back(unbanded_difference("gonial_angle", "Gonial angle L\xE2\x88\x92R", in.gonial_L_deg, in.gonial_R_deg, 1,
                                    "\xC2\xB0", "Co\xE2\x80\x93Go\xE2\x80\x93Me", "Co, Go or Me missing on a side",
                                    "Difference between the angles at gonion (condylion\xE2\x80\x93gonion\xE2\x80\x93menton) "
                                    "of the two sides.",
                                    "no published cut-off found for a 3D gonial angle difference; not banded."));
  out.push_back(unbanded_difference("body_length", "Body length L\xE2\x88\x92R", in.body_L_mm, in.body_R_mm, 2, " mm",
                                    "Go\xE2\x80\x93Me", "Go or Me missing",
                                    "Difference in mandibular body length (gonion to menton) between the sides.",
                                    "no published cut-off found for this 3D distance; not banded."));
  return out;
}

InterpretationInputs interpretation_inputs(const RunSummary& s) {
  InterpretationInputs in;
  if (s.saf.score >= 0) in.saf_score = s.saf.score;
  // The mirror statistics exist only when the surface had vertices.
  if (!s.mirror.per_vertex.empty()) {
    in.mirror_rms_mm = s.mirror.overall.rms;
    in.mirror_p95_mm = s.mirror.overall.p95;
  }
  auto side = [&](const char* name, double& L, double& R) {
    auto it = s.bilateral.find(name);
    if (it == s.bilateral.end()) return;
    L = it->second.L;
    R = it->second.R;
  };
  side("ramus_height_mm", in.ramus_L_mm, in.ramus_R_mm);
  side("gonial_angle_deg", in.gonial_L_deg, in.gonial_R_deg);
  side("body_length_mm", in.body_L_mm, in.body_R_mm);
  if (const Vec3* me = s.landmarks.landmarks.find("Me")) {
    in.menton_to_mandible_plane_mm = s.reference.plane.signed_distance(*me);
    in.menton_to_plane_mm = in.menton_to_mandible_plane_mm;
    if (s.cranial.found) {
      in.menton_to_plane_mm = s.cranial.plane.signed_distance(*me);
      in.menton_plane_cranial = true;
    }
  }
  return in;
}

}  // namespace ms::reports
