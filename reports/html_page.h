// The skeleton shared by MandiSym's HTML pages (report.html, compare.html,
// cohort.html): doctype, head with the title and the shared
// stylesheet inlined, body. The stylesheet is a real file,
// reports/assets/mandisym.css, compiled in as a string at build time
// (reports/CMakeLists.txt, embed_text.cmake). Pages stay self-contained.
#pragma once

#include <string>

namespace ms::reports {

// reports/assets/mandisym.css, as compiled in.
const char* page_css();

// A whole page: body (the markup inside <body>) wrapped in
//   <!DOCTYPE html> <html lang="en"><head> charset, viewport, <title>title</title>
//   <style>page_css()</style></head><body> body </body></html>
// title is HTML-escaped.
std::string html_page(const std::string& title, const std::string& body);

}  // namespace ms::reports
