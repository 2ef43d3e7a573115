// report.pdf: the report's essentials on two A4 pages, composed with cairo
// (vector text through the toy font API, DejaVu Sans), from the run's
// results.json document alone. Page 1: identity, QC banner, headline bands
// (not for a failed run, as in report.html), bilateral measures, missing
// landmarks. Page 2: key views and the note on the bands. A page that runs
// out of room continues on a new page rather than clipping.
//
// Band labels come from core/bands.h, the table report.html uses too.
#include <cairo-pdf.h>
#include <cairo.h>

#include "core/bands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/files.h"
#include "dicomout/dicomout.h"

namespace ms::dicomout {

namespace {

constexpr double kPageW = 595.276, kPageH = 841.890;  // A4 in points
constexpr double kMargin = 48, kWidth = kPageW - 2 * kMargin;
constexpr double kBottom = kPageH - kMargin - 18;  // room for the footer
constexpr const char* kFont = "DejaVu Sans";

struct Rgb {
  double r, g, b;
};
constexpr Rgb kInk{0.10, 0.10, 0.12}, kMuted{0.38, 0.38, 0.42}, kRule{0.78, 0.78, 0.80};
constexpr Rgb kRed{0.70, 0.08, 0.08}, kAmber{0.62, 0.40, 0.00}, kGreen{0.10, 0.45, 0.18}, kGrey{0.45, 0.45, 0.48};

// The drawing state: the context, the vertical cursor (top of the next line) and the page number.
struct Canvas {
  cairo_t* cr = nullptr;
  double y = kMargin;
  int page = 1;
  std::string footer;
};

// --- results.json access: never throws, a missing member is nullptr -------

const Json* member(const Json& root, std::initializer_list<const char*> path) {
  const Json* j = &root;
  for (const char* key : path)
    if (!(j = find_member(*j, key))) return nullptr;
  return j;
}

std::string text_at(const Json& root, std::initializer_list<const char*> path, const std::string& fallback = "-") {
  const Json* j = member(root, path);
  return j && j->is_string() && !j->get<std::string>().empty() ? j->get<std::string>() : fallback;
}

// A number with prec decimals and its unit, or "not computed" (null, absent or not finite).
std::string number(const Json* j, int prec, const std::string& unit = "") {
  if (!j || !j->is_number() || !std::isfinite(j->get<double>())) return "not computed";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, j->get<double>());
  std::string s = b;
  if (s[0] == '-' && s.find_first_not_of("0.", 1) == std::string::npos) s.erase(0, 1);  // "-0.00" reads "0.00"
  return s + unit;
}

// Bytes that are not well-formed UTF-8 become '?' (cairo refuses such text and stops drawing).
std::string clean_utf8(const std::string& s) {
  std::string o;
  for (std::size_t i = 0; i < s.size();) {
    const unsigned char c = s[i];
    const std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    bool ok = n > 0 && i + n <= s.size() && (n > 1 || c >= 0x20 || c == '\t');
    for (std::size_t k = 1; ok && k < n; ++k) ok = (static_cast<unsigned char>(s[i + k]) & 0xC0) == 0x80;
    o += ok ? s.substr(i, n) : "?";
    i += ok ? n : 1;
  }
  return o;
}

// --- text primitives ---------------------------------------------------------

void use_font(cairo_t* cr, double size, bool bold) {
  cairo_select_font_face(cr, kFont, CAIRO_FONT_SLANT_NORMAL, bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
}

void use_colour(cairo_t* cr, const Rgb& c) { cairo_set_source_rgb(cr, c.r, c.g, c.b); }

double text_width(cairo_t* cr, const std::string& s) {
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  return e.x_advance;
}

// Text broken into lines no wider than width in the current font: at spaces,
// and inside a word (between UTF-8 characters) when the word alone is too wide.
std::vector<std::string> wrap(cairo_t* cr, const std::string& text, double width) {
  std::vector<std::string> lines;
  std::string line, word;
  auto place = [&](const std::string& w) {
    const std::string joined = line.empty() ? w : line + " " + w;
    if (text_width(cr, joined) <= width || line.empty()) {
      line = joined;
    } else {
      lines.push_back(line);
      line = w;
    }
    while (text_width(cr, line) > width && line.size() > 1) {  // one word wider than the line
      std::size_t cut = line.size() - 1;
      while (cut > 1 && (text_width(cr, line.substr(0, cut)) > width || (static_cast<unsigned char>(line[cut]) & 0xC0) == 0x80)) --cut;
      lines.push_back(line.substr(0, cut));
      line = line.substr(cut);
    }
  };
  for (char c : clean_utf8(text) + " ") {
    if (c != ' ' && c != '\n') {
      word += c;
      continue;
    }
    if (!word.empty()) place(word);
    word.clear();
    if (c == '\n' && !line.empty()) lines.push_back(line), line.clear();
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

double line_height(double size) { return size * 1.38; }

void draw_footer(Canvas& c) {
  use_font(c.cr, 7.5, false);
  use_colour(c.cr, kMuted);
  cairo_move_to(c.cr, kMargin, kPageH - kMargin + 4);
  cairo_show_text(c.cr, c.footer.c_str());
  const std::string page = "page " + std::to_string(c.page);
  cairo_move_to(c.cr, kMargin + kWidth - text_width(c.cr, page), kPageH - kMargin + 4);
  cairo_show_text(c.cr, page.c_str());
}

void next_page(Canvas& c) {
  draw_footer(c);
  cairo_show_page(c.cr);
  ++c.page;
  c.y = kMargin;
}

// Starts a new page unless height fits below the cursor.
void ensure_room(Canvas& c, double height) {
  if (c.y + height > kBottom && c.y > kMargin) next_page(c);
}

// Wrapped text at the cursor, indented by indent; advances the cursor.
void draw_paragraph(Canvas& c, const std::string& text, double size, bool bold, const Rgb& colour, double indent = 0) {
  use_font(c.cr, size, bold);
  for (const std::string& line : wrap(c.cr, text, kWidth - indent)) {
    ensure_room(c, line_height(size));
    use_font(c.cr, size, bold);  // the footer of a new page changed it
    use_colour(c.cr, colour);
    cairo_move_to(c.cr, kMargin + indent, c.y + size);
    cairo_show_text(c.cr, line.c_str());
    c.y += line_height(size);
  }
}

void draw_heading(Canvas& c, const std::string& text) {
  ensure_room(c, 60);  // a heading is not left alone at the foot of a page
  c.y += 10;
  draw_paragraph(c, text, 12.5, true, kInk);
  use_colour(c.cr, kRule);
  cairo_set_line_width(c.cr, 0.6);
  cairo_move_to(c.cr, kMargin, c.y + 1);
  cairo_line_to(c.cr, kMargin + kWidth, c.y + 1);
  cairo_stroke(c.cr);
  c.y += 6;
}

void rounded_rect(cairo_t* cr, double x, double y, double w, double h, double r) {
  cairo_new_sub_path(cr);
  cairo_arc(cr, x + w - r, y + r, r, -M_PI / 2, 0);
  cairo_arc(cr, x + w - r, y + h - r, r, 0, M_PI / 2);
  cairo_arc(cr, x + r, y + h - r, r, M_PI / 2, M_PI);
  cairo_arc(cr, x + r, y + r, r, M_PI, 3 * M_PI / 2);
  cairo_close_path(cr);
}

// --- page 1 --------------------------------------------------------------------

// Title and the study: series UID, study date, tool version (results.json holds no patient name).
void draw_title_block(Canvas& c, const Json& results) {
  draw_paragraph(c, "Mandibular asymmetry report", 20, true, kInk);
  c.y += 4;
  draw_paragraph(c, "Series " + text_at(results, {"input", "series_uid"}), 8.5, false, kMuted);
  std::string date = text_at(results, {"input", "study_date"});
  if (date.size() == 8 && date.find_first_not_of("0123456789") == std::string::npos)
    date = date.substr(0, 4) + "-" + date.substr(4, 2) + "-" + date.substr(6, 2);
  draw_paragraph(c,
                 "Study date " + date + "  \xC2\xB7  modality " + text_at(results, {"input", "modality"}) + "  \xC2\xB7  MandiSym " +
                     text_at(results, {"tool", "version"}),
                 8.5, false, kMuted);
  c.y += 8;
}

// A check's number with at most 3 decimals and no trailing zeros ("150", "80.432").
std::string short_number(const Json* j) {
  std::string s = number(j, 3);
  if (s.find('.') == std::string::npos) return s;
  s.erase(s.find_last_not_of('0') + 1);
  if (s.back() == '.') s.pop_back();
  return s;
}

// One failed or warned check: "name = value unit (allowed lo to hi): meaning. Source: source".
std::string check_text(const Json& check) {
  const std::string unit = text_at(check, {"unit"}, "");
  std::string s = text_at(check, {"name"}, "?") + " = " + short_number(member(check, {"value"})) + (unit.empty() ? "" : " " + unit);
  const Json* allowed = member(check, {"allowed"});
  if (allowed && allowed->is_array() && allowed->size() == 2) {
    const std::string lo = short_number(&(*allowed)[0]), hi = short_number(&(*allowed)[1]);
    const Json &bottom = (*allowed)[0], &top = (*allowed)[1];
    const bool open_end = !top.is_number() || !std::isfinite(top.get<double>());  // null or infinite: no upper bound
    const bool open_start = !bottom.is_number() || !std::isfinite(bottom.get<double>());  // no lower bound
    s += " (allowed " + (open_end ? "at least " + lo : open_start ? "at most " + hi : lo == hi ? lo : lo + " to " + hi) + ")";
  }
  else if (allowed && allowed->is_string())
    s += " (allowed: " + allowed->get<std::string>() + ")";
  const std::string meaning = text_at(check, {"meaning"}, "");
  if (!meaning.empty()) s += ": " + meaning;
  const std::string source = text_at(check, {"source"}, "");
  return s + (source.empty() ? "" : ". Source: " + source);
}

// The QC banner: red with the failed checks, amber with the warnings, green when every check passed.
void draw_qc_banner(Canvas& c, const Json& results) {
  const std::string status = text_at(results, {"qc", "status"}, "not recorded");
  const bool fail = status == "fail", warn = status == "warn", pass = status == "pass";
  std::vector<std::string> items;
  std::size_t checks = 0;
  if (const Json* list = member(results, {"qc", "checks"}); list && list->is_array())
    for (const Json& k : *list) {
      ++checks;
      const Json* passed = member(k, {"passed"});
      const bool failed_check = passed && passed->is_boolean() && !passed->get<bool>();
      if (failed_check && (!fail || text_at(k, {"severity"}, "fail") == "fail")) items.push_back(check_text(k));
    }
  if (const std::string cause = text_at(results, {"qc", "cause"}, ""); fail && !cause.empty())
    items.insert(items.begin(), "Likely cause: " + cause + ".");
  const std::string title = fail   ? "Result failed quality control \xE2\x80\x94 do not use these numbers."
                            : warn ? "Quality control: warnings \xE2\x80\x94 check the items below before using the numbers."
                            : pass ? "Quality control passed: all " + std::to_string(checks) + " checks within their limits."
                                   : "Quality control status: " + status + ".";
  const Rgb ink = fail ? kRed : warn ? kAmber : pass ? kGreen : kGrey;
  const Rgb fill = fail ? Rgb{0.99, 0.91, 0.91} : warn ? Rgb{1.0, 0.95, 0.83} : pass ? Rgb{0.90, 0.96, 0.90} : Rgb{0.94, 0.94, 0.95};
  use_font(c.cr, 10.5, true);
  const std::vector<std::string> head = wrap(c.cr, title, kWidth - 20);
  use_font(c.cr, 8.5, false);
  std::size_t item_lines = 0;
  for (const auto& it : items) item_lines += wrap(c.cr, it, kWidth - 32).size();
  const double h = 16 + head.size() * line_height(10.5) + item_lines * line_height(8.5) + items.size() * 2;
  ensure_room(c, h);
  rounded_rect(c.cr, kMargin, c.y, kWidth, h, 5);
  use_colour(c.cr, fill);
  cairo_fill_preserve(c.cr);
  use_colour(c.cr, ink);
  cairo_set_line_width(c.cr, 1.4);
  cairo_stroke(c.cr);
  const double bottom = c.y + h;
  c.y += 8;
  for (const auto& line : head) {
    use_font(c.cr, 10.5, true);
    use_colour(c.cr, ink);
    cairo_move_to(c.cr, kMargin + 10, c.y + 10.5);
    cairo_show_text(c.cr, line.c_str());
    c.y += line_height(10.5);
  }
  for (const auto& it : items) {
    use_font(c.cr, 8.5, false);
    use_colour(c.cr, ink);
    cairo_move_to(c.cr, kMargin + 12, c.y + 8.5);
    cairo_show_text(c.cr, "\xE2\x80\xA2");
    draw_paragraph(c, it, 8.5, false, kInk, 22);
    c.y += 2;
  }
  c.y = bottom + 8;
}

// The run's warnings, as report.html shows them up front.
void draw_warnings(Canvas& c, const Json& results) {
  const Json* w = member(results, {"warnings"});
  if (!w || !w->is_array() || w->empty()) return;
  for (const Json& x : *w)
    if (x.is_string()) draw_paragraph(c, "\xE2\x9A\xA0 " + x.get<std::string>(), 8.5, false, kAmber);
  c.y += 4;
}

// interpretation.<key>.band as report.html words it (core/bands.h).
std::string band_label(const std::string& band) { return std::string(band_label_of(band)); }

Rgb band_colour(const std::string& band) {
  return band == "typical" ? kGreen : band == "mild" ? kAmber : band == "marked" ? kRed : kGrey;
}

struct HeadlineRow {
  std::string key, title, value, detail;
};

// One headline number: title and detail, value, band pill, thresholds underneath.
void draw_headline_row(Canvas& c, const Json& results, const HeadlineRow& row) {
  const Json* it = member(results, {"interpretation", row.key.c_str()});
  const std::string band = it ? text_at(*it, {"band"}, "unavailable") : "unavailable";
  const Json* prov = it ? member(*it, {"provisional"}) : nullptr;
  const bool banded = band == "typical" || band == "mild" || band == "marked";
  const std::string pill = band_label(band) + (banded && prov && prov->is_boolean() && prov->get<bool>() ? " \xC2\xB7 provisional" : "");
  ensure_room(c, 62);
  const double top = c.y, col_value = kMargin + 175, col_band = kMargin + 290;
  use_font(c.cr, 10, true);
  use_colour(c.cr, kInk);
  cairo_move_to(c.cr, kMargin, top + 11);
  cairo_show_text(c.cr, row.title.c_str());
  use_font(c.cr, 13, true);
  cairo_move_to(c.cr, col_value, top + 12);
  cairo_show_text(c.cr, row.value.c_str());
  use_font(c.cr, 8.5, true);
  const double pw = text_width(c.cr, pill) + 14;
  rounded_rect(c.cr, col_band, top, pw, 16, 8);
  use_colour(c.cr, band_colour(band));
  cairo_fill(c.cr);
  cairo_set_source_rgb(c.cr, 1, 1, 1);
  cairo_move_to(c.cr, col_band + 7, top + 11.2);
  cairo_show_text(c.cr, pill.c_str());
  c.y = top + 18;
  if (!row.detail.empty()) draw_paragraph(c, row.detail, 8, false, kMuted);
  const std::string thresholds = it ? text_at(*it, {"thresholds"}, "") : "";
  if (!thresholds.empty()) draw_paragraph(c, "Bands: " + thresholds, 7.5, false, kMuted, 10);
  c.y += 7;
}

// The headline interpretation: SAF score, mirror distance p95, menton deviation, ramus height index.
void draw_headline(Canvas& c, const Json& results) {
  draw_heading(c, "Headline");
  const Json* ramus = member(results, {"scores", "bilateral", "ramus_height_mm"});
  const bool cranial = member(results, {"cranial_plane"}) && member(results, {"cranial_plane"})->is_object();
  const std::vector<HeadlineRow> rows = {
      {"saf_score", "SAF asymmetry score", number(member(results, {"interpretation", "saf_score", "value"}), 3, " rad"),
       "0 = perfect symmetry; MandiSym's own metric"},
      {"mirror_distance", "Mirror distance p95", number(member(results, {"interpretation", "mirror_distance", "value"}), 2, " mm"),
       "RMS " + number(member(results, {"scores", "mirror", "rms_mm"}), 2, " mm") + "; band from the 95th percentile of |d|"},
      {"menton_deviation", "Menton deviation", number(member(results, {"interpretation", "menton_deviation", "value"}), 2, " mm"),
       cranial ? "from the cranial mid-sagittal plane" : "from the mandible's own symmetry plane (no cranial plane)"},
      {"ramus_height", "Ramus height index", number(member(results, {"interpretation", "ramus_height", "value"}), 1, " %"),
       "100|L\xE2\x88\x92R|/(L+R) of Co\xE2\x80\x93Go: L " + number(ramus ? member(*ramus, {"L"}) : nullptr, 1, " mm") + ", R " +
           number(ramus ? member(*ramus, {"R"}) : nullptr, 1, " mm")},
  };
  for (const auto& row : rows) draw_headline_row(c, results, row);
}

// "ramus_height_mm" -> "ramus height (mm)".
std::string measure_name(std::string n) {
  std::string unit;
  for (const char* u : {"mm", "deg"})
    if (n.size() > std::string(u).size() + 1 && n.compare(n.size() - std::string(u).size() - 1, std::string::npos, std::string("_") + u) == 0) {
      unit = std::string(u) == "deg" ? " (\xC2\xB0)" : " (mm)";
      n.resize(n.size() - std::string(u).size() - 1);
    }
  std::replace(n.begin(), n.end(), '_', ' ');
  return n + unit;
}

// The bilateral measures: left, right and their difference.
void draw_bilateral_table(Canvas& c, const Json& results) {
  draw_heading(c, "Bilateral measures");
  const double cols[] = {kMargin, kMargin + 220, kMargin + 310, kMargin + 400};
  auto row = [&](const std::string (&cells)[4], bool bold) {
    ensure_room(c, 16);
    use_font(c.cr, 9, bold);
    use_colour(c.cr, kInk);
    for (int k = 0; k < 4; ++k) {
      cairo_move_to(c.cr, cols[k], c.y + 10);
      cairo_show_text(c.cr, clean_utf8(cells[k]).c_str());
    }
    c.y += 15;
  };
  row({"measure", "left", "right", "L\xE2\x88\x92R"}, true);
  const Json* bil = member(results, {"scores", "bilateral"});
  if (!bil || !bil->is_object() || bil->empty()) {
    draw_paragraph(c, "No bilateral measure was computed.", 9, false, kMuted);
    return;
  }
  for (const auto& [name, m] : bil->items())
    row({measure_name(name), number(member(m, {"L"}), 2), number(member(m, {"R"}), 2), number(member(m, {"diff"}), 2)}, false);
}

// Landmarks not found, each with its reason.
void draw_missing_landmarks(Canvas& c, const Json& results) {
  const Json* missing = member(results, {"landmark_detection", "missing"});
  if (!missing || !missing->is_array() || missing->empty()) {
    c.y += 8;
    draw_paragraph(c, "All landmarks were found.", 9, false, kMuted);
    return;
  }
  draw_heading(c, "Landmarks missing");
  for (const Json& n : *missing) {
    if (!n.is_string()) continue;
    const std::string name = n.get<std::string>();
    const std::string why = text_at(results, {"landmark_detection", "why_missing", name.c_str()}, "no reason recorded");
    draw_paragraph(c, name + ": " + why, 9, false, kInk);
  }
}

// --- page 2 --------------------------------------------------------------------

// "view_mirror_front.png" -> "mirror front".
std::string view_caption(const std::string& file) {
  std::string stem = std::filesystem::path(file).stem().string();
  if (stem.rfind("view_", 0) == 0) stem = stem.substr(5);
  std::replace(stem.begin(), stem.end(), '_', ' ');
  return stem;
}

// One PNG scaled to fit the cell (w x h, caption below), or a note when it cannot be read.
void draw_view(cairo_t* cr, const std::string& file, double x, double y, double w, double h) {
  cairo_surface_t* img = cairo_image_surface_create_from_png(file.c_str());
  const double iw = cairo_image_surface_get_width(img), ih = cairo_image_surface_get_height(img);
  const double room = h - 16;
  if (cairo_surface_status(img) == CAIRO_STATUS_SUCCESS && iw > 0 && ih > 0) {
    const double s = std::min(w / iw, room / ih);
    cairo_save(cr);
    cairo_translate(cr, x + (w - iw * s) / 2, y + (room - ih * s) / 2);
    cairo_scale(cr, s, s);
    cairo_set_source_surface(cr, img, 0, 0);
    cairo_paint(cr);
    cairo_restore(cr);
  } else {
    use_font(cr, 8, false);
    use_colour(cr, kMuted);
    cairo_move_to(cr, x + 6, y + room / 2);
    cairo_show_text(cr, "image could not be read");
  }
  cairo_surface_destroy(img);
  use_font(cr, 8, false);
  use_colour(cr, kMuted);
  const std::string caption = clean_utf8(view_caption(file));
  cairo_move_to(cr, x + std::max(0.0, (w - text_width(cr, caption)) / 2), y + h - 4);
  cairo_show_text(cr, caption.c_str());
}

// The key views, two per row, each row as tall as the page allows (at most 4:3 of the cell width).
void draw_key_views(Canvas& c, const Json& results, const std::vector<std::string>& views) {
  draw_heading(c, "Key views");
  if (views.empty()) {
    draw_paragraph(c, "No 3D views were rendered for this run (see log.txt).", 9, false, kMuted);
    return;
  }
  draw_paragraph(c,
                 "In the frame of the fitted symmetry plane; landmarks in green. Mirror distance: red where a side bulges "
                 "beyond its mirror image, blue where it lies inside it.",
                 8, false, kMuted);
  if (text_at(results, {"qc", "status"}) == "fail")
    draw_paragraph(c, "This result failed quality control: the views show what was measured, not a usable result.", 8, true, kRed);
  const double gap = 12, cell_w = (kWidth - gap) / 2;
  const std::size_t rows = (views.size() + 1) / 2;
  const double room = kBottom - c.y - 120;  // leave room for the note on the bands
  const double cell_h = std::clamp(room / rows, 90.0, cell_w * 0.75 + 16);
  for (std::size_t k = 0; k < views.size(); ++k) {
    if (k % 2 == 0) ensure_room(c, cell_h);
    draw_view(c.cr, views[k], kMargin + (k % 2) * (cell_w + gap), c.y, cell_w, cell_h);
    if (k % 2 == 1 || k + 1 == views.size()) c.y += cell_h + 4;
  }
}

// Why the bands are provisional (the paragraph under report.html's headline).
void draw_bands_note(Canvas& c) {
  draw_heading(c, "About the bands");
  draw_paragraph(c,
                 "The bands place each number against published cut-offs where they exist (menton deviation, "
                 "ramus-height asymmetry index), a common convention (mirror distance) or MandiSym's own phantom "
                 "measurements (SAF score: provisional, phantom-derived, not clinically validated). They describe "
                 "size, not a diagnosis; none has been validated for MandiSym's automatic landmarks and plane. The "
                 "published cut-offs were set on radiographs or CBCT against a facial or cranial midline, not against "
                 "the mandible's own symmetry plane. Compare against a cohort or a pre-operative scan. Thresholds, "
                 "sources and every other number: report.html and results.json of the same run.",
                 8.5, false, kInk);
}

cairo_status_t append_to_string(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

void write_report_pdf(const Json& results, const std::vector<std::string>& view_pngs, const std::string& pdf_path) {
  std::string bytes;
  cairo_surface_t* surface = cairo_pdf_surface_create_for_stream(append_to_string, &bytes, kPageW, kPageH);
  const std::string version = text_at(results, {"tool", "version"}, "");
  cairo_pdf_surface_set_metadata(surface, CAIRO_PDF_METADATA_TITLE, "MandiSym mandibular asymmetry report");
  cairo_pdf_surface_set_metadata(surface, CAIRO_PDF_METADATA_CREATOR, clean_utf8("MandiSym " + version).c_str());
  Canvas c;
  c.cr = cairo_create(surface);
  c.footer = clean_utf8("MandiSym " + version + " \xC2\xB7 mandibular asymmetry report \xC2\xB7 describes size, not a diagnosis");
  draw_title_block(c, results);
  draw_qc_banner(c, results);
  draw_warnings(c, results);
  if (text_at(results, {"qc", "status"}) != "fail") draw_headline(c, results);
  draw_bilateral_table(c, results);
  draw_missing_landmarks(c, results);
  next_page(c);
  draw_key_views(c, results, view_pngs);
  draw_bands_note(c);
  draw_footer(c);
  cairo_show_page(c.cr);
  const cairo_status_t drawn = cairo_status(c.cr);
  cairo_destroy(c.cr);
  cairo_surface_finish(surface);
  const cairo_status_t finished = cairo_surface_status(surface);
  cairo_surface_destroy(surface);
  for (cairo_status_t s : {drawn, finished})
    if (s != CAIRO_STATUS_SUCCESS) throw Error(ExitCode::OutputFailed, pdf_path + ": cannot compose the PDF report: " + cairo_status_to_string(s));
  write_file_atomic(pdf_path, bytes);
}

}  // namespace ms::dicomout
