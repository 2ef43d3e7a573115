#include "reports/html_page.h"

#include "reports/page_css.h"  // generated from assets/mandisym.css: kPageCss
#include "reports/writers.h"

namespace ms::reports {

const char* page_css() { return kPageCss; }

std::string html_page(const std::string& title, const std::string& body) {
  std::string page =
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>";
  page.reserve(page.size() + title.size() + sizeof kPageCss + body.size() + 64);
  page += html_escape(title);
  page += "</title>\n<style>\n";
  page += kPageCss;
  page += "</style></head><body>\n";
  page += body;
  page += "</body></html>\n";
  return page;
}

}  // namespace ms::reports
