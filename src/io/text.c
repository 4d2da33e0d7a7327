/* Text for the text readers and writers: lines, tokens and comments, and
 * the exact conversions between decimal text and doubles (parsing and the
 * shortest form that reads back as the same value). */
#include "io/io.h"

#include <errno.h>
#include <float.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Text scanning                                                             */
/* ------------------------------------------------------------------------ */

void io_text_init(io_text *t, const char *data, size_t size) {
  t->data = data;
  t->size = size;
  t->pos = 0;
  t->line = 0;
}

int io_text_next_line(io_text *t, const char **line, size_t *len) {
  if (t->pos >= t->size) return 0;
  const char *start = t->data + t->pos;
  size_t left = t->size - t->pos;
  const char *nl = memchr(start, '\n', left);
  size_t n = nl ? (size_t)(nl - start) : left;
  /* A '\r' before the '\n' ends the line too: "\r\n" (Windows) is one
   * break, a lone '\r' (classic Mac OS) another, so files mixing the three
   * conventions read line by line alike. */
  const char *cr = n ? memchr(start, '\r', n) : NULL;
  if (cr && cr + 1 < start + n) {
    n = (size_t)(cr - start);
    t->pos += n + 1;
  } else {
    t->pos += nl ? n + 1 : n;
    if (cr) n--; /* the '\r' of "\r\n", or one ending the data */
  }
  t->line++;
  *line = start;
  *len = n;
  return 1;
}

static int is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static int is_sep(char c, int seps) {
  return is_space(c) || (seps == IO_SEP_XYZ && (c == ',' || c == ';'));
}

void io_cursor_init(io_cursor *c, const char *s, size_t len, int seps) {
  c->p = s;
  c->end = s + len;
  c->seps = seps;
}

int io_next_token(io_cursor *c, io_token *tok) {
  const char *p = c->p;
  while (p < c->end && is_sep(*p, c->seps))
    p++;
  if (p == c->end) {
    c->p = p;
    return 0;
  }
  const char *s = p;
  while (p < c->end && !is_sep(*p, c->seps))
    p++;
  tok->s = s;
  tok->len = (size_t)(p - s);
  c->p = p;
  return 1;
}

size_t io_count_tokens(const io_cursor *c) {
  io_cursor copy = *c;
  io_token tok;
  size_t n = 0;
  while (io_next_token(&copy, &tok))
    n++;
  return n;
}

int io_token_is(io_token tok, const char *word) {
  size_t n = strlen(word);
  return tok.len == n && memcmp(tok.s, word, n) == 0;
}

const char *io_token_repr(io_token tok, char out[48]) {
  size_t n = tok.len < 40 ? tok.len : 40;
  for (size_t i = 0; i < n; i++) {
    unsigned char ch = (unsigned char)tok.s[i];
    out[i] = (ch >= 0x20 && ch < 0x7f) ? (char)ch : '?';
  }
  if (tok.len > n) {
    memcpy(out + n, "...", 3);
    n += 3;
  }
  out[n] = '\0';
  return out;
}

size_t io_strip_comment(const char *line, size_t len) {
  const char *hash = memchr(line, '#', len);
  return hash ? (size_t)(hash - line) : len;
}

/* ------------------------------------------------------------------------ */
/* Numbers                                                                   */
/* ------------------------------------------------------------------------ */

#if defined(__SIZEOF_INT128__)
/* Exact decimal <-> binary conversions in 128-bit integers (a GCC/Clang
 * extension; without it everything goes through strtod / snprintf). */
__extension__ typedef unsigned __int128 io_u128;

/* 5^0 .. 5^27 (5^27 < 2^63) */
static const uint64_t k_pow5[28] = {1ULL,
                                    5ULL,
                                    25ULL,
                                    125ULL,
                                    625ULL,
                                    3125ULL,
                                    15625ULL,
                                    78125ULL,
                                    390625ULL,
                                    1953125ULL,
                                    9765625ULL,
                                    48828125ULL,
                                    244140625ULL,
                                    1220703125ULL,
                                    6103515625ULL,
                                    30517578125ULL,
                                    152587890625ULL,
                                    762939453125ULL,
                                    3814697265625ULL,
                                    19073486328125ULL,
                                    95367431640625ULL,
                                    476837158203125ULL,
                                    2384185791015625ULL,
                                    11920928955078125ULL,
                                    59604644775390625ULL,
                                    298023223876953125ULL,
                                    1490116119384765625ULL,
                                    7450580596923828125ULL};

static int bitlen128(io_u128 x) {
  uint64_t hi = (uint64_t)(x >> 64), lo = (uint64_t)x;
  if (hi) return 128 - __builtin_clzll(hi);
  return lo ? 64 - __builtin_clzll(lo) : 0;
}

/* The double nearest to n * 2^e2 (ties to even); `sticky`: the true value
 * is a little more than n. n > 0; the result must be normal. */
static double round_to_double(io_u128 n, int sticky, int e2) {
  int shift = bitlen128(n) - 53;
  uint64_t mant;
  if (shift <= 0) return ldexp((double)(uint64_t)n, e2); /* exact (sticky is 0 here) */
  mant = (uint64_t)(n >> shift);
  io_u128 rem = n - ((io_u128)mant << shift), half = (io_u128)1 << (shift - 1);
  if (rem > half || (rem == half && (sticky || (mant & 1)))) mant++;
  return ldexp((double)mant, shift + e2);
}
#endif

/* Exact powers of ten of a double (10^22 is the largest). */
static const double k_pow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                 1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* Clinger's fast path: a decimal with at most 19 significant digits whose
 * mantissa fits in 53 bits and whose power of ten is exact is one correctly
 * rounded multiplication or division. Returns 0 when it does not apply. */
static int parse_fast(const char *s, size_t len, double *out) {
  size_t i = 0;
  int neg = 0;
  if (i < len && (s[i] == '+' || s[i] == '-')) neg = s[i++] == '-';
  uint64_t m = 0;
  int sig = 0, digits = 0;
  long e10 = 0;
  while (i < len && s[i] >= '0' && s[i] <= '9') {
    int d = s[i++] - '0';
    digits++;
    if (m == 0 && d == 0) continue;
    if (++sig > 19) return 0;
    m = m * 10 + (uint64_t)d;
  }
  if (i < len && s[i] == '.') {
    i++;
    while (i < len && s[i] >= '0' && s[i] <= '9') {
      int d = s[i++] - '0';
      digits++;
      e10--;
      if (m == 0 && d == 0) continue;
      if (++sig > 19) return 0;
      m = m * 10 + (uint64_t)d;
    }
  }
  if (digits == 0) return 0;
  if (i < len && (s[i] == 'e' || s[i] == 'E')) {
    i++;
    int eneg = 0;
    if (i < len && (s[i] == '+' || s[i] == '-')) eneg = s[i++] == '-';
    long ev = 0;
    int edigits = 0;
    while (i < len && s[i] >= '0' && s[i] <= '9') {
      if (ev < 100000) ev = ev * 10 + (s[i] - '0');
      i++;
      edigits++;
    }
    if (edigits == 0) return 0;
    e10 += eneg ? -ev : ev;
  }
  if (i != len) return 0;
  double v;
  if (m == 0) {
    v = 0.0;
  } else {
    if (m <= ((uint64_t)1 << 53) && e10 >= -22 && e10 <= 22) {
      v = e10 >= 0 ? (double)m * k_pow10[e10] : (double)m / k_pow10[-e10];
    } else {
#if defined(__SIZEOF_INT128__)
      /* up to 19 digits (m < 2^64) and |e10| <= 27 (5^27 < 2^63): exact
       * integer arithmetic, one rounding. m * 10^e10 = m * 5^e10 * 2^e10. */
      if (e10 < -27 || e10 > 27) return 0;
      if (e10 >= 0) {
        v = round_to_double((io_u128)m * k_pow5[e10], 0, (int)e10);
      } else {
        int k = 128 - bitlen128(m); /* m * 2^k in [2^127, 2^128) */
        io_u128 num = (io_u128)m << k, den = k_pow5[-e10];
        io_u128 q = num / den;
        v = round_to_double(q, num != q * den, (int)e10 - k);
      }
#else
      return 0;
#endif
    }
  }
  *out = neg ? -v : v;
  return 1;
}

int io_parse_double(const char *s, size_t len, double *out) {
  if (len == 0) return 0;
  if (parse_fast(s, len, out)) return 1;
  /* Everything else (17 significant digits, large exponents, inf, nan) goes
   * to strtod on a NUL-terminated copy; the buffer itself may not be
   * terminated. strtod follows LC_NUMERIC, so translate the '.'. */
  char buf[128];
  if (len >= sizeof buf) return 0;
  memcpy(buf, s, len);
  buf[len] = '\0';
  if (memchr(buf, '\0', len)) return 0;
  const char *dp = localeconv()->decimal_point;
  if (dp && dp[0] && !(dp[0] == '.' && dp[1] == '\0')) {
    if (dp[1] != '\0' || strchr(buf, dp[0])) return 0; /* unusual locale */
    for (char *q = buf; *q; q++)
      if (*q == '.') *q = dp[0];
  }
  char *end = NULL;
  double v = strtod(buf, &end);
  if (end != buf + len) return 0;
  *out = v;
  return 1;
}

int io_parse_u64(const char *s, size_t len, unsigned long long *out) {
  if (len == 0) return 0;
  unsigned long long v = 0;
  for (size_t i = 0; i < len; i++) {
    if (s[i] < '0' || s[i] > '9') return 0;
    unsigned d = (unsigned)(s[i] - '0');
    if (v > (~0ULL - d) / 10) return 0;
    v = v * 10 + d;
  }
  *out = v;
  return 1;
}

/* printf follows LC_NUMERIC: put back a '.' for whatever decimal point the
 * locale used (possibly several bytes). */
static size_t fix_decimal_point(char *buf, size_t n) {
  size_t o = 0;
  int in_dp = 0;
  for (size_t i = 0; i < n; i++) {
    char c = buf[i];
    int known = (c >= '0' && c <= '9') || c == '-' || c == '+' || c == 'e' || c == '.' ||
                c == 'i' || c == 'n' || c == 'f' || c == 'a';
    if (known) {
      buf[o++] = c;
      in_dp = 0;
    } else if (!in_dp) {
      buf[o++] = '.';
      in_dp = 1;
    }
  }
  buf[o] = '\0';
  return o;
}

#if defined(__SIZEOF_INT128__)
/* floor(m * 2^e * 10^q) exactly, and in *up whether rounding to nearest
 * (ties to even) goes one higher; all ones when the operands leave the
 * range that 128-bit integers cover. */
static uint64_t scaled_digits(uint64_t m, int e, int q, int *up) {
  const uint64_t fail = ~0ULL;
  io_u128 num, den, d, r;
  /* m * 2^e * 10^q = m * 5^q * 2^(e+q) */
  int s = e + q;
  if (q >= 0) {
    if (q > 27) return fail;
    num = (io_u128)m * k_pow5[q]; /* < 2^53 * 2^63 */
    if (s >= 0) {
      if (s > 10) return fail; /* the result has at most 17 digits anyway */
      *up = 0;
      return (uint64_t)(num << s);
    }
    if (s < -127) return fail;
    d = num >> -s;
    r = num - (d << -s);
    io_u128 half = (io_u128)1 << (-s - 1);
    *up = r > half || (r == half && (d & 1));
    return d >= (io_u128)fail ? fail : (uint64_t)d;
  }
  if (-q > 27) return fail;
  den = k_pow5[-q];
  if (s >= 0) {
    if (s > 74) return fail;
    num = (io_u128)m << s;
  } else {
    if (s < -60) return fail;
    num = m;
    den <<= -s;
  }
  d = num / den;
  r = num - d * den;
  *up = 2 * r > den || (2 * r == den && (d & 1));
  return d >= (io_u128)fail ? fail : (uint64_t)d;
}

/* printf("%.<p>g", v) for finite nonzero v with p <= 17, without printf
 * (which is slow and follows the locale). Returns 0 if v is outside the
 * range handled here. */
static size_t format_g(char *buf, double v, int p) {
  static const uint64_t pow10[19] = {1ULL,
                                     10ULL,
                                     100ULL,
                                     1000ULL,
                                     10000ULL,
                                     100000ULL,
                                     1000000ULL,
                                     10000000ULL,
                                     100000000ULL,
                                     1000000000ULL,
                                     10000000000ULL,
                                     100000000000ULL,
                                     1000000000000ULL,
                                     10000000000000ULL,
                                     100000000000000ULL,
                                     1000000000000000ULL,
                                     10000000000000000ULL,
                                     100000000000000000ULL,
                                     1000000000000000000ULL};
  uint64_t bits;
  memcpy(&bits, &v, sizeof bits);
  int neg = (int)(bits >> 63);
  int be = (int)((bits >> 52) & 0x7ff);
  uint64_t m = bits & ((1ULL << 52) - 1);
  if (be == 0x7ff || (be == 0 && m == 0)) return 0;
  int e;
  if (be == 0) {
    e = -1074;
  } else {
    m |= 1ULL << 52;
    e = be - 1075;
  }
  /* the decimal exponent x of v: 10^x <= |v| < 10^(x+1), then digits */
  int x = (int)floor(log10(fabs(v)));
  /* log10 may be off by one near powers of ten: correct x until the exact
   * scaled value has p digits before the point; then round (a value that
   * rounds up to 10^p prints as 10^(p-1) at x+1, as %g does) */
  uint64_t d = 0;
  int up = 0, ok = 0;
  for (int attempt = 0; attempt < 4 && !ok; attempt++) {
    d = scaled_digits(m, e, p - 1 - x, &up);
    if (d == ~0ULL) return 0;
    if (d >= pow10[p])
      x++;
    else if (d < pow10[p - 1])
      x--;
    else
      ok = 1;
  }
  if (!ok) return 0;
  d += (uint64_t)up;
  if (d == pow10[p]) {
    d = pow10[p - 1];
    x++;
  }
  char dig[20];
  for (int i = p - 1; i >= 0; i--) {
    dig[i] = (char)('0' + d % 10);
    d /= 10;
  }
  int nd = p;
  while (nd > 1 && dig[nd - 1] == '0')
    nd--;
  size_t o = 0;
  if (neg) buf[o++] = '-';
  if (x < -4 || x >= p) {
    buf[o++] = dig[0];
    if (nd > 1) {
      buf[o++] = '.';
      for (int i = 1; i < nd; i++)
        buf[o++] = dig[i];
    }
    buf[o++] = 'e';
    buf[o++] = x < 0 ? '-' : '+';
    int ax = x < 0 ? -x : x;
    if (ax >= 100) buf[o++] = (char)('0' + ax / 100);
    buf[o++] = (char)('0' + ax / 10 % 10);
    buf[o++] = (char)('0' + ax % 10);
  } else if (x >= 0) {
    for (int i = 0; i <= x; i++)
      buf[o++] = dig[i];
    if (nd > x + 1) {
      buf[o++] = '.';
      for (int i = x + 1; i < nd; i++)
        buf[o++] = dig[i];
    }
  } else {
    buf[o++] = '0';
    buf[o++] = '.';
    for (int i = 0; i < -x - 1; i++)
      buf[o++] = '0';
    for (int i = 0; i < nd; i++)
      buf[o++] = dig[i];
  }
  buf[o] = '\0';
  return o;
}
#else
static size_t format_g(char *buf, double v, int p) {
  (void)buf;
  (void)v;
  (void)p;
  return 0;
}
#endif

size_t io_format_value(char *buf, size_t cap, double v, bsurf_type type) {
  int n;
  size_t fast;
  switch (type) {
  case BSURF_FLOAT64:
    if (cap >= 32 && (fast = format_g(buf, v, 17)) > 0) return fast;
    n = snprintf(buf, cap, "%.17g", v);
    break;
  case BSURF_FLOAT32:
    v = io_type_convert(v, BSURF_FLOAT32);
    if (cap >= 32 && (fast = format_g(buf, v, 9)) > 0) return fast;
    n = snprintf(buf, cap, "%.9g", v);
    break;
  default: n = snprintf(buf, cap, "%lld", (long long)io_type_convert(v, type)); return (size_t)n;
  }
  if (n < 0) n = 0;
  if ((size_t)n >= cap) n = (int)cap - 1;
  return fix_decimal_point(buf, (size_t)n);
}
