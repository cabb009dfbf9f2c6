// Expression engine, stage 1: front end. A lexer and a recursive-descent parser that resolve
// names (variables, parameters, constants, functions), fix precedence, enforce the size and
// nesting limits and report errors with a location, producing a syntax tree (AstNode, children
// first) for the lowering.
#include "internal.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

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
  Fn fn;
};
constexpr FunctionSpec kFunctions[] = {
    {"sin", 1, Fn::Sin},     {"cos", 1, Fn::Cos},     {"tan", 1, Fn::Tan},
    {"asin", 1, Fn::Asin},   {"acos", 1, Fn::Acos},   {"atan", 1, Fn::Atan},
    {"atan2", 2, Fn::Atan2}, {"sinh", 1, Fn::Sinh},   {"cosh", 1, Fn::Cosh},
    {"tanh", 1, Fn::Tanh},   {"asinh", 1, Fn::Asinh}, {"acosh", 1, Fn::Acosh},
    {"atanh", 1, Fn::Atanh}, {"exp", 1, Fn::Exp},     {"log", 1, Fn::Log},
    {"sqrt", 1, Fn::Sqrt},   {"abs", 1, Fn::Abs},     {"pow", 2, Fn::Pow},
    {"min", 2, Fn::Min},     {"max", 2, Fn::Max},     {"step", 1, Fn::Step},
    {"clamp", 3, Fn::Clamp}, {"if", 3, Fn::If},
};

const FunctionSpec* find_function(const std::string& name) {
  for (const auto& f : kFunctions)
    if (name == f.name) return &f;
  return nullptr;
}

enum class Tok {
  Num, Id, LParen, RParen, Comma, Plus, Minus, Star, Slash, Caret, Less, LessEq, Greater,
  GreaterEq, End
};

bool is_comparison(Tok k) {
  return k == Tok::Less || k == Tok::LessEq || k == Tok::Greater || k == Tok::GreaterEq;
}

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
    const bool eq_next = i + 1 < n && text[i + 1] == '=';
    switch (ch) {
      case '(': k = Tok::LParen; break;
      case ')': k = Tok::RParen; break;
      case ',': k = Tok::Comma; break;
      case '+': k = Tok::Plus; break;
      case '-': k = Tok::Minus; break;
      case '/': k = Tok::Slash; break;
      case '^': k = Tok::Caret; break;
      case '<':
        k = eq_next ? Tok::LessEq : Tok::Less;
        len = eq_next ? 2 : 1;
        break;
      case '>':
        k = eq_next ? Tok::GreaterEq : Tok::Greater;
        len = eq_next ? 2 : 1;
        break;
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
                "expressions use numbers, names, + - * / ^, parentheses, function calls and "
                "comparisons < <= > >= inside if(...)");
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

/// A short excerpt of `text` around `pos`, for one-line messages about long texts.
std::string excerpt(const std::string& text, std::size_t pos) {
  constexpr std::size_t kWidth = 30;
  const std::size_t from = pos > kWidth ? pos - kWidth : 0;
  const std::size_t to = std::min(text.size(), pos + kWidth);
  std::string part = text.substr(from, to - from);
  for (char& ch : part)  // one line, whatever the text contains
    if (std::iscntrl(static_cast<unsigned char>(ch))) ch = ' ';
  return (from > 0 ? "..." : "") + part + (to < text.size() ? "..." : "");
}

struct FrontEnd {
  const std::string& text;
  const std::vector<std::string>& variables;  // stripped names
  const std::map<std::string, double>& parameters;
  const int max_depth;
  std::vector<Token> toks;
  std::vector<std::size_t> match;  // token index of the matching ')' for each '(' (or npos)
  std::size_t k = 0;
  int depth = 0;
  bool call_like_variables = false;  // some variable is written name(arg)
  ParseResult out;

  FrontEnd(const std::string& t, const std::vector<std::string>& v,
           const std::map<std::string, double>& p, int max_d)
      : text(t), variables(v), parameters(p), max_depth(max_d) {
    toks = lex(text);
    match.assign(toks.size(), std::string::npos);
    std::vector<std::size_t> open;
    for (std::size_t i = 0; i < toks.size(); ++i) {
      if (toks[i].kind == Tok::LParen) open.push_back(i);
      if (toks[i].kind == Tok::RParen && !open.empty()) {
        match[open.back()] = i;
        open.pop_back();
      }
    }
    for (const std::string& name : variables)
      if (name.find('(') != std::string::npos) call_like_variables = true;
  }

  const Token& peek(std::size_t ahead = 0) const {
    return toks[std::min(k + ahead, toks.size() - 1)];
  }
  const Token& next() { return toks[k < toks.size() - 1 ? k++ : k]; }

  [[noreturn]] void error_at(const Token& t, const std::string& what, const std::string& hint) {
    fail_at(text, t.pos, t.kind == Tok::End ? 1 : t.len, what, hint);
  }

  /// One nesting level (see ExpressionOptions::max_depth) for the lifetime of the guard.
  struct Level {
    FrontEnd& fe;
    explicit Level(FrontEnd& f) : fe(f) {
      if (++fe.depth > fe.max_depth) {
        const Token& t = fe.peek();
        throw Error("expression nesting is deeper than the limit of " +
                    std::to_string(fe.max_depth) + " levels (ExpressionOptions::max_depth) at "
                    "column " + std::to_string(t.pos + 1) + " of " +
                    std::to_string(fe.text.size()) + " near \"" + excerpt(fe.text, t.pos) +
                    "\" (hint: parentheses, function calls, unary signs and exponents each add "
                    "a level; simplify the expression or raise ExpressionOptions::max_depth)");
      }
    }
    ~Level() { --fe.depth; }
  };

  void expect(Tok kind, const std::string& what) {
    const Token& t = peek();
    if (t.kind != kind) {
      std::string hint = kind == Tok::RParen ? "check that parentheses are balanced"
                                             : "check the syntax near this point";
      if (is_comparison(t.kind))
        hint = "comparisons are allowed only as the condition of if(cond, a, b)";
      error_at(t, "expected " + what + ", got " + describe(t), hint);
    }
    next();
  }

  /// Appends a node whose span starts at token `start_tok` and ends at the last consumed one.
  std::uint32_t add(AstNode node, std::size_t start_tok, const std::vector<std::uint32_t>& kids,
                    const std::vector<std::uint8_t>& flags = {}) {
    node.pos = static_cast<std::uint32_t>(toks[start_tok].pos);
    const Token& last = toks[k > 0 ? k - 1 : 0];
    node.end = static_cast<std::uint32_t>(last.pos + last.len);
    node.first = static_cast<std::uint32_t>(out.kids.size());
    node.count = static_cast<std::uint32_t>(kids.size());
    out.kids.insert(out.kids.end(), kids.begin(), kids.end());
    if (flags.empty())
      out.flags.insert(out.flags.end(), kids.size(), 0);
    else
      out.flags.insert(out.flags.end(), flags.begin(), flags.end());
    out.nodes.push_back(std::move(node));
    return static_cast<std::uint32_t>(out.nodes.size() - 1);
  }
  std::uint32_t leaf(AstNode node, const Token& t) {
    node.pos = static_cast<std::uint32_t>(t.pos);
    node.end = static_cast<std::uint32_t>(t.pos + t.len);
    node.first = static_cast<std::uint32_t>(out.kids.size());
    out.nodes.push_back(std::move(node));
    return static_cast<std::uint32_t>(out.nodes.size() - 1);
  }
  static AstNode compound(AstKind kind) {
    AstNode n(kind);
    n.located = true;
    return n;
  }

  void parse() {
    parse_sum();
    const Token& t = peek();
    if (t.kind != Tok::End) {
      std::string hint = t.kind == Tok::RParen
                             ? "unbalanced ')'"
                             : is_comparison(t.kind)
                                   ? "comparisons are allowed only as the condition of "
                                     "if(cond, a, b)"
                                   : "an operator is missing (implicit multiplication like '2x' "
                                     "is not supported; write '2*x')";
      error_at(t, "unexpected " + describe(t), hint);
    }
  }

  // Chains of + - (and of * /) become one n-ary node: no nesting, linear cost.
  std::uint32_t parse_sum() {
    std::size_t start = k;
    std::uint32_t first = parse_product();
    if (peek().kind != Tok::Plus && peek().kind != Tok::Minus) return first;
    std::vector<std::uint32_t> kids{first};
    std::vector<std::uint8_t> flags{0};
    while (peek().kind == Tok::Plus || peek().kind == Tok::Minus) {
      flags.push_back(next().kind == Tok::Minus);
      kids.push_back(parse_product());
    }
    return add(compound(AstKind::Sum), start, kids, flags);
  }

  std::uint32_t parse_product() {
    std::size_t start = k;
    std::uint32_t first = parse_unary();
    if (peek().kind != Tok::Star && peek().kind != Tok::Slash) return first;
    std::vector<std::uint32_t> kids{first};
    std::vector<std::uint8_t> flags{0};
    while (peek().kind == Tok::Star || peek().kind == Tok::Slash) {
      flags.push_back(next().kind == Tok::Slash);
      kids.push_back(parse_unary());
    }
    return add(compound(AstKind::Product), start, kids, flags);
  }

  std::uint32_t parse_unary() {
    std::size_t start = k;
    if (peek().kind == Tok::Plus) {
      next();
      Level level(*this);
      return parse_unary();
    }
    if (peek().kind == Tok::Minus) {
      next();
      Level level(*this);
      std::uint32_t s = parse_unary();
      return add(compound(AstKind::Neg), start, {s});
    }
    return parse_power();
  }

  std::uint32_t parse_power() {
    std::size_t start = k;
    std::uint32_t b = parse_primary();
    if (peek().kind == Tok::Caret) {
      next();
      Level level(*this);
      std::uint32_t e = parse_unary();  // right-associative, allows x^-2
      return add(compound(AstKind::Power), start, {b, e});
    }
    return b;
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

  std::uint32_t variable(int index, const Token& first, std::size_t start_tok) {
    AstNode node(AstKind::Variable);
    node.index = index;
    if (start_tok == k - 1) return leaf(std::move(node), first);
    return add(std::move(node), start_tok, {});
  }

  std::uint32_t parse_primary() {
    const Token& t = peek();
    switch (t.kind) {
      case Tok::Num: {
        next();
        AstNode node(AstKind::Number);
        node.text = t.s;
        return leaf(std::move(node), t);
      }
      case Tok::LParen: {
        next();
        std::uint32_t s;
        {
          Level level(*this);
          s = parse_sum();
        }
        expect(Tok::RParen, "')' to close the '(' at column " + std::to_string(t.pos + 1));
        // The parenthesised node keeps its own span (the parentheses add no node).
        return s;
      }
      case Tok::Id:
        return parse_identifier();
      default:
        error_at(t, "expected a number, a name or '(', got " + describe(t),
                 t.kind == Tok::End ? "the expression ends too early"
                                    : is_comparison(t.kind)
                                          ? "comparisons are allowed only as the condition of "
                                            "if(cond, a, b)"
                                          : "check the syntax near this point");
    }
  }

  /// The condition of if(): lhs CMP rhs, exactly one comparison.
  void parse_condition(std::vector<std::uint32_t>& args, Cmp& cmp, const Token& id) {
    args.push_back(parse_sum());
    const Token& t = peek();
    if (!is_comparison(t.kind))
      error_at(t, "expected a comparison (<, <=, >, >=) in the condition of if(), got " +
                      describe(t),
               "write if(x < y, a, b): the first argument compares two expressions");
    next();
    cmp = t.kind == Tok::Less ? Cmp::Lt
          : t.kind == Tok::LessEq ? Cmp::Le
          : t.kind == Tok::Greater ? Cmp::Gt
                                  : Cmp::Ge;
    args.push_back(parse_sum());
    if (is_comparison(peek().kind))
      error_at(peek(), "chained comparison in the condition of if()",
               "compare two expressions only (nest if() calls for more conditions)");
    (void)id;
  }

  /// An unknown call-like name: a variable that is not listed or a misspelt function, whichever
  /// is closer (`call`: the whole call as written, without spaces).
  [[noreturn]] void fail_unknown_call(const Token& id, std::size_t close, const std::string& call) {
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
    else if (best_fn <= allowed_fn && best_fn < static_cast<int>(fn_name.size()))
      suggestion = " (did you mean the function '" + fn_name + "'?)";
    else
      suggestion = did_you_mean(call, candidates());
    fail_at(text, id.pos, toks[close].pos + 1 - id.pos,
            "unknown identifier '" + call + "'" + suggestion, identifiers_hint());
  }

  /// The arguments of a call of f (the next token is its '('), checked against f's arity.
  std::uint32_t parse_call(const Token& id, std::size_t start, const FunctionSpec* f) {
    next();  // '('
    std::vector<std::uint32_t> args;
    Cmp cmp = Cmp::Lt;
    {
      Level level(*this);
      if (f->fn == Fn::If) {
        if (peek().kind != Tok::RParen) parse_condition(args, cmp, id);
      } else if (peek().kind != Tok::RParen) {
        args.push_back(parse_sum());
      }
      while (peek().kind == Tok::Comma) {
        next();
        args.push_back(parse_sum());
      }
    }
    if (peek().kind != Tok::RParen)
      error_at(peek(), "expected ',' or ')' in the arguments of " + id.s + "(), got " +
                           describe(peek()),
               is_comparison(peek().kind)
                   ? "comparisons are allowed only as the condition of if(cond, a, b)"
                   : "check that parentheses are balanced");
    next();
    // if(): the condition counts as one argument (two operands).
    const int got = static_cast<int>(args.size()) - (f->fn == Fn::If && !args.empty() ? 1 : 0);
    if (got != f->arity)
      fail_at(text, id.pos, toks[k - 1].pos + 1 - id.pos,
              "function '" + id.s + "' takes " + std::to_string(f->arity) + " argument" +
                  (f->arity == 1 ? "" : "s") + ", got " + std::to_string(got),
              f->fn == Fn::If      ? "write if(x < y, a, b)"
              : f->fn == Fn::Clamp ? "write clamp(x, lo, hi)"
              : f->arity == 1      ? "write " + id.s + "(u)"
                                   : "write " + id.s + "(u, v)");
    AstNode node = compound(AstKind::Call);
    node.fn = f->fn;
    node.cmp = cmp;
    return add(std::move(node), start, args);
  }

  std::uint32_t parse_identifier() {
    std::size_t start = k;
    const Token id = next();
    if (peek().kind == Tok::LParen) {
      std::size_t open = k;
      std::size_t close = match[open];
      if (close == std::string::npos)
        error_at(toks[open], "unclosed '('", "check that parentheses are balanced");
      const FunctionSpec* f = find_function(id.s);
      // A call-like variable name (x(E), q(psi1)) wins over a function of the same name. Only
      // looked up when such variables exist and the parenthesis is short (a name, not a
      // formula), so long function arguments are not copied.
      std::string call;
      auto call_text = [&] {
        if (call.empty()) call = strip_spaces(text.substr(id.pos, toks[close].pos + 1 - id.pos));
        return call;
      };
      if (call_like_variables && (!f || close - open <= 16)) {
        auto it = std::find(variables.begin(), variables.end(), call_text());
        if (it != variables.end()) {
          k = close + 1;
          return variable(static_cast<int>(it - variables.begin()), id, start);
        }
      }
      if (!f) fail_unknown_call(id, close, call_text());
      return parse_call(id, start, f);
    }
    // Plain identifier.
    auto it = std::find(variables.begin(), variables.end(), id.s);
    if (it != variables.end()) return variable(static_cast<int>(it - variables.begin()), id, start);
    auto p = parameters.find(id.s);
    if (p != parameters.end()) {
      double v = p->second;
      if (!std::isfinite(v))
        error_at(id, "parameter '" + id.s + "' is " + fmt(v),
                 "give the parameter a finite value before building the expression");
      out.used_parameters[id.s] = v;
      AstNode node(AstKind::Parameter);
      node.text = id.s;
      node.value = v;
      return leaf(std::move(node), id);
    }
    if (id.s == "pi") return leaf(AstNode(AstKind::Pi), id);
    if (id.s == "e") return leaf(AstNode(AstKind::E), id);
    if (find_function(id.s))
      error_at(id, "function '" + id.s + "' used without arguments",
               "call it as " + id.s + "(...)");
    error_at(id, "unknown identifier '" + id.s + "'" + did_you_mean(id.s, candidates()),
             identifiers_hint());
  }
};

}  // namespace

std::string function_list() {
  std::string s;
  for (const auto& f : kFunctions) {
    if (!s.empty()) s += ", ";
    s += f.name;
  }
  return s;
}

ParseResult parse_front_end(const std::string& text, const std::vector<std::string>& variables,
                            const std::map<std::string, double>& parameters,
                            const ExpressionOptions& opt) {
  if (text.size() > opt.max_length)
    throw Error("expression \"" + excerpt(text, 0) + "\" is " + std::to_string(text.size()) +
                " characters long, more than the limit of " + std::to_string(opt.max_length) +
                " (ExpressionOptions::max_length) (hint: split it into smaller expressions or "
                "raise ExpressionOptions::max_length)");
  FrontEnd fe(text, variables, parameters, opt.max_depth);
  fe.parse();
  return std::move(fe.out);
}

}  // namespace expr_detail
}  // namespace refdyn
