// Expression engine, stage 1: front end. A lexer and a recursive-descent parser that resolve
// names (variables, parameters, constants, functions), fix precedence and report errors with a
// location, producing a fully parenthesised text for GiNaC's parser.
#include "internal.hpp"

#include "refdyn/error.hpp"
#include "refdyn/text.hpp"

#include <cln/float.h>

#include <algorithm>
#include <cctype>
#include <cmath>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

std::string strip_spaces(const std::string& s) {
  std::string out;
  for (char ch : s)
    if (!std::isspace(static_cast<unsigned char>(ch))) out += ch;
  return out;
}

bool is_ident_start(char ch) { return std::isalpha(static_cast<unsigned char>(ch)) || ch == '_'; }
bool is_ident_char(char ch) { return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_'; }

/// "expression "TEXT": WHAT at column C\n    TEXT\n    ^^^\n(hint: HINT)"
[[noreturn]] void fail_at(const std::string& text, std::size_t pos, std::size_t len,
                          const std::string& what, const std::string& hint) {
  std::string msg = "expression \"" + text + "\": " + what;
  if (pos != std::string::npos) {
    msg += " at column " + std::to_string(pos + 1) + "\n    " + text + "\n    ";
    msg += std::string(pos, ' ') + std::string(std::max<std::size_t>(len, 1), '^');
    msg += "\n";
  } else {
    msg += " ";
  }
  if (!hint.empty()) msg += "(hint: " + hint + ")";
  throw Error(msg);
}

namespace {

struct FunctionSpec {
  const char* name;
  int arity;
};
constexpr FunctionSpec kFunctions[] = {
    {"sin", 1},   {"cos", 1},   {"tan", 1},   {"asin", 1}, {"acos", 1}, {"atan", 1},
    {"atan2", 2}, {"sinh", 1},  {"cosh", 1},  {"tanh", 1}, {"asinh", 1}, {"acosh", 1},
    {"atanh", 1}, {"exp", 1},   {"log", 1},   {"sqrt", 1}, {"abs", 1},  {"pow", 2},
    {"min", 2},   {"max", 2},
};

const FunctionSpec* find_function(const std::string& name) {
  for (const auto& f : kFunctions)
    if (name == f.name) return &f;
  return nullptr;
}

std::string function_list() {
  std::string s;
  for (const auto& f : kFunctions) {
    if (!s.empty()) s += ", ";
    s += f.name;
  }
  return s;
}

enum class Tok { Num, Id, LParen, RParen, Comma, Plus, Minus, Star, Slash, Caret, End };

struct Token {
  Tok kind;
  std::size_t pos;
  std::size_t len;
  std::string s;
};

std::vector<Token> lex(const std::string& text) {
  std::vector<Token> out;
  std::size_t i = 0, n = text.size();
  while (i < n) {
    char ch = text[i];
    if (std::isspace(static_cast<unsigned char>(ch))) {
      ++i;
      continue;
    }
    std::size_t start = i;
    auto digit = [&](std::size_t k) {
      return k < n && std::isdigit(static_cast<unsigned char>(text[k]));
    };
    if (digit(i) || (ch == '.' && digit(i + 1))) {
      while (digit(i)) ++i;
      if (i < n && text[i] == '.') {
        ++i;
        while (digit(i)) ++i;
      }
      if (i < n && (text[i] == 'e' || text[i] == 'E')) {
        std::size_t k = i + 1;
        if (k < n && (text[k] == '+' || text[k] == '-')) ++k;
        if (digit(k)) {
          i = k;
          while (digit(i)) ++i;
        }
      }
      out.push_back({Tok::Num, start, i - start, text.substr(start, i - start)});
      continue;
    }
    if (is_ident_start(ch)) {
      while (i < n && is_ident_char(text[i])) ++i;
      out.push_back({Tok::Id, start, i - start, text.substr(start, i - start)});
      continue;
    }
    Tok k;
    std::size_t len = 1;
    switch (ch) {
      case '(': k = Tok::LParen; break;
      case ')': k = Tok::RParen; break;
      case ',': k = Tok::Comma; break;
      case '+': k = Tok::Plus; break;
      case '-': k = Tok::Minus; break;
      case '/': k = Tok::Slash; break;
      case '^': k = Tok::Caret; break;
      case '*':
        if (i + 1 < n && text[i + 1] == '*') {
          k = Tok::Caret;
          len = 2;
        } else {
          k = Tok::Star;
        }
        break;
      default:
        fail_at(text, i, 1, std::string("unexpected character '") + ch + "'",
                "expressions use numbers, names, + - * / ^, parentheses and function calls");
    }
    out.push_back({k, start, len, text.substr(start, len)});
    i += len;
  }
  out.push_back({Tok::End, n, 0, ""});
  return out;
}

std::string describe(const Token& t) {
  if (t.kind == Tok::End) return "end of expression";
  return "'" + t.s + "'";
}

/// A sub-expression of the source, with its GiNaC text; used to locate evaluation errors.
struct FrontEnd {
  const std::string& text;
  const std::vector<std::string>& variables;           // stripped names
  const std::map<std::string, double>& parameters;
  std::vector<Token> toks;
  std::size_t k = 0;
  GiNaC::symtab symtab;
  const std::vector<GiNaC::realsymbol>& symbols;       // per variable
  std::vector<Node> nodes;
  std::map<std::string, double> used_parameters;

  FrontEnd(const std::string& t, const std::vector<std::string>& v,
           const std::map<std::string, double>& p, const std::vector<GiNaC::realsymbol>& syms)
      : text(t), variables(v), parameters(p), symbols(syms) {
    toks = lex(text);
  }

  const Token& peek(std::size_t ahead = 0) const {
    return toks[std::min(k + ahead, toks.size() - 1)];
  }
  const Token& next() { return toks[k < toks.size() - 1 ? k++ : k]; }

  [[noreturn]] void error_at(const Token& t, const std::string& what, const std::string& hint) {
    fail_at(text, t.pos, t.kind == Tok::End ? 1 : t.len, what, hint);
  }

  void expect(Tok kind, const std::string& what) {
    const Token& t = peek();
    if (t.kind != kind) {
      std::string hint = kind == Tok::RParen ? "check that parentheses are balanced"
                                             : "check the syntax near this point";
      error_at(t, "expected " + what + ", got " + describe(t), hint);
    }
    next();
  }

  std::string record(std::size_t start_tok, const std::string& g) {
    std::size_t pos = toks[start_tok].pos;
    const Token& last = toks[k > 0 ? k - 1 : 0];
    nodes.push_back({pos, last.pos + last.len, g});
    return g;
  }

  std::string parse() {
    std::string g = parse_sum();
    const Token& t = peek();
    if (t.kind != Tok::End) {
      std::string hint = t.kind == Tok::RParen
                             ? "unbalanced ')'"
                             : "an operator is missing (implicit multiplication like '2x' is "
                               "not supported; write '2*x')";
      error_at(t, "unexpected " + describe(t), hint);
    }
    return g;
  }

  std::string parse_sum() {
    std::size_t start = k;
    std::string s = parse_product();
    while (peek().kind == Tok::Plus || peek().kind == Tok::Minus) {
      char op = next().kind == Tok::Plus ? '+' : '-';
      std::string t = parse_product();
      s = record(start, "(" + s + op + t + ")");
    }
    return s;
  }

  std::string parse_product() {
    std::size_t start = k;
    std::string s = parse_unary();
    while (peek().kind == Tok::Star || peek().kind == Tok::Slash) {
      char op = next().kind == Tok::Star ? '*' : '/';
      std::string t = parse_unary();
      s = record(start, "(" + s + op + t + ")");
    }
    return s;
  }

  std::string parse_unary() {
    std::size_t start = k;
    if (peek().kind == Tok::Plus) {
      next();
      return parse_unary();
    }
    if (peek().kind == Tok::Minus) {
      next();
      std::string s = parse_unary();
      return record(start, "(-" + s + ")");
    }
    return parse_power();
  }

  std::string parse_power() {
    std::size_t start = k;
    std::string b = parse_primary();
    if (peek().kind == Tok::Caret) {
      next();
      std::string e = parse_unary();  // right-associative, allows x^-2
      return record(start, "(" + b + "^" + e + ")");
    }
    return b;
  }

  // Index of the ')' matching the '(' at token index `open`, or npos.
  std::size_t matching_paren(std::size_t open) const {
    int depth = 0;
    for (std::size_t i = open; i < toks.size(); ++i) {
      if (toks[i].kind == Tok::LParen) ++depth;
      if (toks[i].kind == Tok::RParen && --depth == 0) return i;
    }
    return std::string::npos;
  }

  std::vector<std::string> candidates() const {
    std::vector<std::string> c = variables;
    for (const auto& [name, v] : parameters) c.push_back(name);
    c.push_back("pi");
    c.push_back("e");
    for (const auto& f : kFunctions) c.push_back(f.name);
    return c;
  }

  std::string identifiers_hint() const {
    return "identifiers must be variables listed by the caller, parameters, the constants pi "
           "and e, or the functions " +
           function_list();
  }

  std::string variable_placeholder(int index) {
    std::string ph = "rdvar" + std::to_string(index);
    symtab[ph] = symbols[index];
    return ph;
  }

  std::string parse_primary() {
    std::size_t start = k;
    const Token& t = peek();
    switch (t.kind) {
      case Tok::Num:
        next();
        return "(" + t.s + ")";
      case Tok::LParen: {
        next();
        std::string s = parse_sum();
        expect(Tok::RParen, "')' to close the '(' at column " + std::to_string(t.pos + 1));
        return record(start, "(" + s + ")");
      }
      case Tok::Id:
        return parse_identifier();
      default:
        error_at(t, "expected a number, a name or '(', got " + describe(t),
                 t.kind == Tok::End ? "the expression ends too early"
                                    : "check the syntax near this point");
    }
  }

  std::string parse_identifier() {
    std::size_t start = k;
    const Token id = next();
    if (peek().kind == Tok::LParen) {
      std::size_t open = k;
      std::size_t close = matching_paren(open);
      if (close == std::string::npos)
        error_at(toks[open], "unclosed '('", "check that parentheses are balanced");
      std::string call = strip_spaces(text.substr(id.pos, toks[close].pos + 1 - id.pos));
      auto it = std::find(variables.begin(), variables.end(), call);
      if (it != variables.end()) {
        k = close + 1;
        return variable_placeholder(static_cast<int>(it - variables.begin()));
      }
      const FunctionSpec* f = find_function(id.s);
      if (!f) {
        // Unknown: a variable that is not listed or a misspelt function, whichever is closer.
        int best_var = 1 << 30, best_fn = 1 << 30;
        std::string var_name, fn_name;
        for (const std::string& v : variables) {
          int d = edit_distance(call, v);
          if (d < best_var) best_var = d, var_name = v;
        }
        for (const auto& fs : kFunctions) {
          int d = edit_distance(id.s, fs.name);
          if (d < best_fn) best_fn = d, fn_name = fs.name;
        }
        const int allowed_var = std::max<int>(2, static_cast<int>(call.size()) / 3);
        const int allowed_fn = std::max<int>(2, static_cast<int>(id.s.size()) / 3);
        std::string suggestion;
        if (best_var <= allowed_var && best_var <= best_fn)
          suggestion = " (did you mean '" + var_name + "'?)";
        else if (best_fn <= allowed_fn)
          suggestion = " (did you mean the function '" + fn_name + "'?)";
        else
          suggestion = did_you_mean(call, candidates());
        fail_at(text, id.pos, toks[close].pos + 1 - id.pos,
                "unknown identifier '" + call + "'" + suggestion, identifiers_hint());
      }
      next();  // '('
      std::vector<std::string> args;
      if (peek().kind != Tok::RParen) {
        args.push_back(parse_sum());
        while (peek().kind == Tok::Comma) {
          next();
          args.push_back(parse_sum());
        }
      }
      if (peek().kind != Tok::RParen)
        error_at(peek(), "expected ',' or ')' in the arguments of " + id.s + "(), got " +
                             describe(peek()),
                 "check that parentheses are balanced");
      next();
      if (static_cast<int>(args.size()) != f->arity)
        fail_at(text, id.pos, toks[k - 1].pos + 1 - id.pos,
                "function '" + id.s + "' takes " + std::to_string(f->arity) + " argument" +
                    (f->arity == 1 ? "" : "s") + ", got " + std::to_string(args.size()),
                f->arity == 1 ? "write " + id.s + "(u)" : "write " + id.s + "(u, v)");
      std::string g;
      const std::string name = id.s;
      if (name == "min" || name == "max") {
        const char* sign = name == "min" ? "-" : "+";
        g = "(((" + args[0] + ")+(" + args[1] + ")" + sign + "abs((" + args[0] + ")-(" +
            args[1] + ")))/2)";
      } else if (name == "pow") {
        g = "((" + args[0] + ")^(" + args[1] + "))";
      } else {
        g = name + "(" + args[0];
        for (std::size_t i = 1; i < args.size(); ++i) g += "," + args[i];
        g += ")";
      }
      return record(start, g);
    }
    // Plain identifier.
    auto it = std::find(variables.begin(), variables.end(), id.s);
    if (it != variables.end()) return variable_placeholder(static_cast<int>(it - variables.begin()));
    auto p = parameters.find(id.s);
    if (p != parameters.end()) {
      double v = p->second;
      if (!std::isfinite(v))
        error_at(id, "parameter '" + id.s + "' is " + fmt(v),
                 "give the parameter a finite value before building the expression");
      used_parameters[id.s] = v;
      std::string ph = "rdpar_" + id.s;
      if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0)
        symtab[ph] = GiNaC::numeric(static_cast<long>(v));
      else
        symtab[ph] = GiNaC::numeric(cln::cl_float(v, cln::float_format_dfloat));
      return ph;
    }
    if (id.s == "pi") {
      symtab["rdpi"] = GiNaC::Pi;
      return "rdpi";
    }
    if (id.s == "e") {
      symtab["rde"] = GiNaC::exp(ex(1));
      return "rde";
    }
    if (find_function(id.s))
      error_at(id, "function '" + id.s + "' used without arguments",
               "call it as " + id.s + "(...)");
    error_at(id, "unknown identifier '" + id.s + "'" + did_you_mean(id.s, candidates()),
             identifiers_hint());
  }
};

}  // namespace

ParseResult parse_front_end(const std::string& text, const std::vector<std::string>& variables,
                            const std::map<std::string, double>& parameters,
                            const std::vector<GiNaC::realsymbol>& symbols) {
  FrontEnd fe(text, variables, parameters, symbols);
  ParseResult r;
  r.ginac_text = fe.parse();
  r.symtab = std::move(fe.symtab);
  r.nodes = std::move(fe.nodes);
  r.used_parameters = std::move(fe.used_parameters);
  return r;
}

}  // namespace expr_detail
}  // namespace refdyn
