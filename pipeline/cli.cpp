#include "pipeline/cli.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include "core/error.h"

namespace ms::cli {

std::string Args::get(const std::string& n, const std::string& def) const {
  auto it = values.find(n);
  return it == values.end() ? def : it->second;
}

double Args::number(const std::string& n, double def) const {
  auto it = values.find(n);
  if (it == values.end()) return def;
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (end == it->second.c_str() || *end != '\0' || !std::isfinite(v))
    throw Error(ExitCode::Usage, "--" + n + ": expected a number, got '" + it->second + "'");
  return v;
}

double Args::number_in(const std::string& n, double def, double lo, double hi, const char* unit) const {
  const double v = number(n, def);
  if (v < lo || v > hi) {
    std::ostringstream m;
    m << "--" << n << ": " << get(n) << " is outside the allowed range [" << lo << ", " << hi << "]" << (*unit ? " " : "") << unit;
    throw Error(ExitCode::Usage, m.str());
  }
  return v;
}

double Args::ranged(const std::string& n, double def, const char* unit) const {
  const auto it = ranges.find(n);
  if (it == ranges.end()) throw Error(ExitCode::Internal, "--" + n + ": no range declared");
  return number_in(n, def, it->second.first, it->second.second, unit);
}

Vec3 Args::vec3(const std::string& n, const Vec3& def) const {
  auto it = values.find(n);
  if (it == values.end()) return def;
  std::vector<double> parts;
  std::stringstream ss(it->second);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || *end != '\0' || !std::isfinite(v))
      throw Error(ExitCode::Usage, "--" + n + ": expected x,y,z numbers, got '" + it->second + "'");
    parts.push_back(v);
  }
  if (parts.size() == 1) return {parts[0], parts[0], parts[0]};
  if (parts.size() != 3) throw Error(ExitCode::Usage, "--" + n + ": expected 1 or 3 comma-separated numbers");
  return {parts[0], parts[1], parts[2]};
}

Args parse(const CommandSpec& spec, const std::vector<std::string>& argv) {
  Args a;
  for (const auto& o : spec.options)
    if (!std::isnan(o.lo)) a.ranges[o.name] = {o.lo, o.hi};
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& s = argv[i];
    if (s == "--") {
      if (spec.passthrough.empty()) throw Error(ExitCode::Usage, spec.name + ": unexpected '--' (see mandisym " + spec.name + " --help)");
      a.passthrough.assign(argv.begin() + static_cast<std::ptrdiff_t>(i) + 1, argv.end());
      break;
    }
    if (s.size() > 1 && s[0] == '-' && !(s.size() > 1 && (std::isdigit(static_cast<unsigned char>(s[1])) || s[1] == '.'))) {
      std::string name = s.substr(s[1] == '-' ? 2 : 1);
      std::string inline_value;
      bool has_inline = false;
      if (auto eq = name.find('='); eq != std::string::npos) {
        inline_value = name.substr(eq + 1);
        name = name.substr(0, eq);
        has_inline = true;
      }
      if (name == "o") name = "output";
      if (name == "q") name = "quiet";
      if (name == "h") name = "help";
      const OptionSpec* opt = nullptr;
      for (const auto& o : spec.options)
        if (o.name == name) opt = &o;
      if (!opt) throw Error(ExitCode::Usage, spec.name + ": unknown option '" + s + "' (see mandisym " + spec.name + " --help)");
      if (opt->value_name.empty()) {
        a.values[name] = "1";
      } else if (has_inline) {
        a.values[name] = inline_value;
      } else {
        if (i + 1 >= argv.size()) throw Error(ExitCode::Usage, spec.name + ": option --" + name + " needs a value");
        a.values[name] = argv[++i];
      }
    } else {
      a.positional.push_back(s);
    }
  }
  if (a.positional.size() != spec.arguments.size() && !a.has("help")) {
    std::string names;
    for (const auto& [n, h] : spec.arguments) names += " " + n;
    throw Error(ExitCode::Usage, spec.name + ": expected " + std::to_string(spec.arguments.size()) +
                                     " argument(s):" + names + " (see mandisym " + spec.name + " --help)");
  }
  return a;
}

std::string help(const CommandSpec& spec) {
  std::ostringstream o;
  o << "mandisym " << spec.name;
  for (const auto& [n, h] : spec.arguments) o << " " << n;
  o << " [options]" << (spec.passthrough.empty() ? "" : " [-- OPTIONS...]") << "\n\n  " << spec.synopsis << "\n\n";
  if (!spec.description.empty()) o << spec.description << "\n\n";
  if (!spec.arguments.empty()) {
    o << "Arguments:\n";
    for (const auto& [n, h] : spec.arguments) o << "  " << n << "\n      " << h << "\n";
    o << "\n";
  }
  o << "Options:\n";
  for (const auto& opt : spec.options) {
    o << "  --" << opt.name;
    if (!opt.value_name.empty()) o << " " << opt.value_name;
    o << "\n      " << opt.help;
    if (!opt.default_value.empty()) o << " (default: " << opt.default_value << ")";
    if (!std::isnan(opt.lo)) o << " [" << opt.lo << " to " << opt.hi << "]";
    o << "\n";
  }
  if (!spec.passthrough.empty()) o << "\n  -- OPTIONS...\n      " << spec.passthrough << "\n";
  return o.str();
}

}  // namespace ms::cli
