/* The file layer's entry points (format dispatch by extension, whole-file
 * reads, atomic writes through a temporary file) and the helpers shared by
 * the per-format readers and writers. */
#include "io/io.h"

#include <errno.h>
#include <float.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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

/* ------------------------------------------------------------------------ */
/* Value types                                                               */
/* ------------------------------------------------------------------------ */

size_t io_type_size(bsurf_type type) {
  switch (type) {
  case BSURF_INT8:
  case BSURF_UINT8: return 1;
  case BSURF_INT16:
  case BSURF_UINT16: return 2;
  case BSURF_INT32:
  case BSURF_UINT32:
  case BSURF_FLOAT32: return 4;
  case BSURF_FLOAT64: return 8;
  }
  return 8;
}

const char *io_type_name(bsurf_type type) {
  switch (type) {
  case BSURF_INT8: return "char";
  case BSURF_UINT8: return "uchar";
  case BSURF_INT16: return "short";
  case BSURF_UINT16: return "ushort";
  case BSURF_INT32: return "int";
  case BSURF_UINT32: return "uint";
  case BSURF_FLOAT32: return "float";
  case BSURF_FLOAT64: return "double";
  }
  return "double";
}

int io_type_parse(const char *s, size_t len, bsurf_type *type) {
  static const struct {
    const char *name;
    bsurf_type type;
  } names[] = {{"char", BSURF_INT8},      {"uchar", BSURF_UINT8},    {"short", BSURF_INT16},
               {"ushort", BSURF_UINT16},  {"int", BSURF_INT32},      {"uint", BSURF_UINT32},
               {"float", BSURF_FLOAT32},  {"double", BSURF_FLOAT64}, {"int8", BSURF_INT8},
               {"uint8", BSURF_UINT8},    {"int16", BSURF_INT16},    {"uint16", BSURF_UINT16},
               {"int32", BSURF_INT32},    {"uint32", BSURF_UINT32},  {"float32", BSURF_FLOAT32},
               {"float64", BSURF_FLOAT64}};
  io_token tok = {s, len};
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
    if (io_token_is(tok, names[i].name)) {
      *type = names[i].type;
      return 1;
    }
  }
  return 0;
}

int io_type_is_integer(bsurf_type type) {
  return type != BSURF_FLOAT32 && type != BSURF_FLOAT64;
}

double io_type_convert(double v, bsurf_type type) {
  double lo, hi;
  switch (type) {
  case BSURF_INT8:
    lo = -128.0;
    hi = 127.0;
    break;
  case BSURF_UINT8:
    lo = 0.0;
    hi = 255.0;
    break;
  case BSURF_INT16:
    lo = -32768.0;
    hi = 32767.0;
    break;
  case BSURF_UINT16:
    lo = 0.0;
    hi = 65535.0;
    break;
  case BSURF_INT32:
    lo = -2147483648.0;
    hi = 2147483647.0;
    break;
  case BSURF_UINT32:
    lo = 0.0;
    hi = 4294967295.0;
    break;
  case BSURF_FLOAT32:
    /* Beyond FLT_MAX the conversion is undefined in ISO C: do IEEE's rounding
     * by hand (up to FLT_MAX + half an ulp rounds down to FLT_MAX). */
    if (v > FLT_MAX) return v < 0x1.ffffffp127 ? (double)FLT_MAX : (double)INFINITY;
    if (v < -FLT_MAX) return v > -0x1.ffffffp127 ? -(double)FLT_MAX : -(double)INFINITY;
    return (double)(float)v;
  case BSURF_FLOAT64:
  default: return v;
  }
  if (isnan(v)) return 0.0;
  v = round(v);
  if (v < lo) v = lo;
  if (v > hi) v = hi;
  return v + 0.0; /* no negative zero */
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

/* ------------------------------------------------------------------------ */
/* Growable arrays                                                           */
/* ------------------------------------------------------------------------ */

void io_faces_init(io_faces *f) {
  memset(f, 0, sizeof *f);
}

void io_faces_free(io_faces *f) {
  free(f->tri);
  io_faces_init(f);
}

void io_faces_begin(io_faces *f) {
  f->corners = 0;
}

bsurf_status io_faces_corner(io_faces *f, uint32_t index) {
  if (f->corners >= 2) {
    if (f->count == f->cap) {
      size_t cap = f->cap ? 2 * f->cap : 1024;
      if (cap > (size_t)-1 / (3 * sizeof(uint32_t))) return BSURF_ERR_NOMEM;
      uint32_t *tri = realloc(f->tri, cap * 3 * sizeof(uint32_t));
      if (!tri) return BSURF_ERR_NOMEM;
      f->tri = tri;
      f->cap = cap;
    }
    uint32_t *t = f->tri + 3 * f->count++;
    t[0] = f->first;
    t[1] = f->prev;
    t[2] = index;
  } else if (f->corners == 0) {
    f->first = index;
  }
  f->prev = index;
  f->corners++;
  return BSURF_OK;
}

void io_faces_move(io_faces *f, bsurf_cloud *cloud) {
  free(cloud->faces);
  cloud->faces = NULL;
  cloud->face_count = 0;
  if (f->count) {
    uint32_t *tri = realloc(f->tri, f->count * 3 * sizeof(uint32_t));
    cloud->faces = tri ? tri : f->tri;
    cloud->face_count = f->count;
  } else {
    free(f->tri);
  }
  io_faces_init(f);
}

bsurf_status io_dvec_push(io_dvec *d, const double *values, size_t count) {
  if (count > d->cap - d->n) {
    size_t cap = d->cap ? d->cap : 4096;
    while (cap - d->n < count) {
      if (cap > (size_t)-1 / (2 * sizeof(double))) return BSURF_ERR_NOMEM;
      cap *= 2;
    }
    double *v = realloc(d->v, cap * sizeof(double));
    if (!v) return BSURF_ERR_NOMEM;
    d->v = v;
    d->cap = cap;
  }
  memcpy(d->v + d->n, values, count * sizeof(double));
  d->n += count;
  return BSURF_OK;
}

double *io_dvec_take(io_dvec *d) {
  double *v = d->v;
  if (d->n == 0) {
    free(v);
    v = NULL;
  } else if (d->n < d->cap) {
    double *s = realloc(v, d->n * sizeof(double));
    if (s) v = s;
  }
  d->v = NULL;
  d->n = d->cap = 0;
  return v;
}

/* ------------------------------------------------------------------------ */
/* Checked output                                                            */
/* ------------------------------------------------------------------------ */

void io_write_bytes(io_writer *w, const void *p, size_t n) {
  if (w->failed || n == 0) return;
  errno = 0;
  if (fwrite(p, 1, n, w->f) != n) {
    w->failed = 1;
    w->err_no = errno ? errno : EIO;
  }
}

void io_write_str(io_writer *w, const char *s) {
  io_write_bytes(w, s, strlen(s));
}

void io_write_fmt(io_writer *w, const char *fmt, ...) {
  if (w->failed) return;
  va_list ap;
  va_start(ap, fmt);
  errno = 0;
  int r = vfprintf(w->f, fmt, ap);
  va_end(ap);
  if (r < 0) {
    w->failed = 1;
    w->err_no = errno ? errno : EIO;
  }
}

/* ------------------------------------------------------------------------ */
/* Formats                                                                   */
/* ------------------------------------------------------------------------ */

static int ext_is(const char *ext, const char *name) {
  size_t n = strlen(name);
  if (strlen(ext) != n) return 0;
  for (size_t i = 0; i < n; i++) {
    char c = ext[i];
    if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
    if (c != name[i]) return 0;
  }
  return 1;
}

bsurf_format bsurf_format_from_path(const char *path) {
  if (!path) return BSURF_FORMAT_UNKNOWN;
  const char *base = strrchr(path, '/');
  base = base ? base + 1 : path;
  const char *dot = strrchr(base, '.');
  if (!dot || dot == base) return BSURF_FORMAT_UNKNOWN;
  const char *ext = dot + 1;
  if (ext_is(ext, "ply")) return BSURF_FORMAT_PLY;
  if (ext_is(ext, "off")) return BSURF_FORMAT_OFF;
  if (ext_is(ext, "obj")) return BSURF_FORMAT_OBJ;
  if (ext_is(ext, "xyz") || ext_is(ext, "txt") || ext_is(ext, "pts")) return BSURF_FORMAT_XYZ;
  return bsurf_format_from_name(ext);
}

/* ---- formats by name and by content (docs/formats.md) ---- */

bsurf_format bsurf_format_from_name(const char *name) {
  static const struct {
    const char *name;
    bsurf_format format;
  } names[] = {{"ply", BSURF_FORMAT_PLY}, {"off", BSURF_FORMAT_OFF}, {"obj", BSURF_FORMAT_OBJ},
               {"xyz", BSURF_FORMAT_XYZ}, {"txt", BSURF_FORMAT_XYZ}, {"pts", BSURF_FORMAT_XYZ},
               {"pcd", BSURF_FORMAT_PCD}, {"las", BSURF_FORMAT_LAS}, {"laz", BSURF_FORMAT_LAS},
               {"csv", BSURF_FORMAT_CSV}, {"asc", BSURF_FORMAT_CSV}};
  if (!name) return BSURF_FORMAT_UNKNOWN;
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
    if (ext_is(name, names[i].name)) return names[i].format;
  return BSURF_FORMAT_UNKNOWN;
}

const char *bsurf_format_name(bsurf_format format) {
  static const char *const names[] = {"", "ply", "off", "obj", "xyz", "pcd", "las", "csv"};
  return (unsigned)format < sizeof names / sizeof names[0] ? names[format] : "";
}

/* The first line of the data (at most 64 bytes of it) starts with `word`
 * followed by the end of the line or a blank. */
static int starts_with_word(const char *p, size_t size, const char *word) {
  size_t n = strlen(word);
  if (size < n || memcmp(p, word, n) != 0) return 0;
  return size == n || p[n] == '\n' || p[n] == '\r' || p[n] == ' ' || p[n] == '\t';
}

bsurf_format bsurf_format_detect(const void *data, size_t size) {
  const char *p = data;
  if (!p) return BSURF_FORMAT_UNKNOWN;
  if (size >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) { /* a UTF-8 byte order mark */
    p += 3;
    size -= 3;
  }
  if (size >= 4 && memcmp(p, "LASF", 4) == 0) return BSURF_FORMAT_LAS;
  if (starts_with_word(p, size, "ply")) return BSURF_FORMAT_PLY;
  if (size >= 6 && memcmp(p, "# .PCD", 6) == 0) return BSURF_FORMAT_PCD;
  if (starts_with_word(p, size, "VERSION")) return BSURF_FORMAT_PCD;
  /* OFF's keyword, after comment and blank lines: OFF NOFF COFF STOFF ... */
  size_t i = 0;
  while (i < size) {
    while (i < size && (p[i] == ' ' || p[i] == '\t' || p[i] == '\r' || p[i] == '\n'))
      i++;
    if (i < size && p[i] == '#') {
      while (i < size && p[i] != '\n')
        i++;
      continue;
    }
    break;
  }
  size_t j = i;
  while (j < size && j - i < 16 && p[j] >= 'A' && p[j] <= 'Z')
    j++;
  if (j - i >= 3 && memcmp(p + j - 3, "OFF", 3) == 0 &&
      (j == size || p[j] == '\n' || p[j] == '\r' || p[j] == ' ' || p[j] == '\t' ||
       (p[j] >= '0' && p[j] <= '9')))
    return BSURF_FORMAT_OFF;
  return BSURF_FORMAT_UNKNOWN;
}

/* Text without a signature or a known extension: OBJ when a line starts
 * with "v ", else a point list (CSV/XYZ, header line or not). */
static bsurf_format sniff_text(const char *p, size_t size) {
  size_t n = size < 65536 ? size : 65536;
  for (size_t i = 0; i + 1 < n; i++)
    if ((i == 0 || p[i - 1] == '\n') && p[i] == 'v' && (p[i + 1] == ' ' || p[i + 1] == '\t'))
      return BSURF_FORMAT_OBJ;
  return BSURF_FORMAT_CSV;
}

int bsurf_format_keeps_fields(bsurf_format format) {
  return format == BSURF_FORMAT_PLY || format == BSURF_FORMAT_PCD || format == BSURF_FORMAT_LAS ||
         format == BSURF_FORMAT_CSV;
}

static void clear_error(bsurf_failure *err) {
  if (err) {
    err->line = 0;
    err->byte = -1;
    err->message[0] = '\0';
  }
}

static const char k_unknown_ext[] =
    "unknown file extension (use .ply, .pcd, .las, .csv, .asc, .off, .obj, .xyz, .txt or .pts)";

/* ------------------------------------------------------------------------ */
/* Reading                                                                   */
/* ------------------------------------------------------------------------ */

bsurf_status bsurf_read_buffer(const void *data, size_t size, bsurf_format format,
                               bsurf_cloud *cloud, bsurf_failure *err) {
  clear_error(err);
  if (!cloud) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no cloud given");
  bsurf_cloud_init(cloud);
  if (!data && size) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no data given");
  const char *p = data ? (const char *)data : "";
  /* Text files saved by Windows tools may start with a UTF-8 byte order
   * mark (PLY keeps every byte: binary offsets must stay exact). */
  if (format != BSURF_FORMAT_PLY && format != BSURF_FORMAT_LAS && size >= 3 &&
      memcmp(p, "\xEF\xBB\xBF", 3) == 0) {
    p += 3;
    size -= 3;
  }
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  bsurf_status st;
  switch (format) {
  case BSURF_FORMAT_PLY: st = bsurf_io_read_ply(p, size, &c, err); break;
  case BSURF_FORMAT_OFF: st = bsurf_io_read_off(p, size, &c, err); break;
  case BSURF_FORMAT_OBJ: st = bsurf_io_read_obj(p, size, &c, err); break;
  case BSURF_FORMAT_XYZ:
  case BSURF_FORMAT_CSV: st = bsurf_io_read_xyz(p, size, &c, err); break;
  case BSURF_FORMAT_PCD: st = bsurf_io_read_pcd(p, size, &c, err); break;
  case BSURF_FORMAT_LAS: st = bsurf_io_read_las(p, size, &c, err); break;
  case BSURF_FORMAT_UNKNOWN:
  default: st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1, "unknown file format"); break;
  }
  if (st != BSURF_OK) {
    bsurf_cloud_free(&c);
    if (err && !err->message[0])
      bsurf_fail(err, st, err->line, err->byte, "%s", bsurf_strerror(st));
    return st;
  }
  *cloud = c;
  return BSURF_OK;
}

bsurf_status bsurf_read(const char *path, bsurf_cloud *cloud, bsurf_failure *err) {
  clear_error(err);
  if (!cloud) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no cloud given");
  bsurf_cloud_init(cloud);
  if (!path) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path given");
  bsurf_format format = bsurf_format_from_path(path);
  int is_stdin = strcmp(path, "-") == 0;

  FILE *f = is_stdin ? stdin : fopen(path, "rb");
  if (!f) return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open: %s", strerror(errno));
  struct stat sb;
  size_t cap = 1 << 16;
  if (fstat(fileno(f), &sb) == 0) {
    if (S_ISDIR(sb.st_mode)) {
      if (!is_stdin) fclose(f);
      return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot read: it is a directory");
    }
    if (S_ISREG(sb.st_mode)) {
      if ((unsigned long long)sb.st_size >= (unsigned long long)((size_t)-1 / 2)) {
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "the file is too large (%lld bytes)",
                          (long long)sb.st_size);
      }
      cap = (size_t)sb.st_size + 1; /* +1: reach EOF without growing */
    }
  }
  char *buf = malloc(cap);
  size_t n = 0;
  if (!buf) {
    if (!is_stdin) fclose(f);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory reading the file (%zu bytes)",
                      cap);
  }
  for (;;) {
    if (n == cap) {
      if (cap > (size_t)-1 / 4) {
        free(buf);
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "the file is too large");
      }
      char *nb = realloc(buf, cap * 2);
      if (!nb) {
        free(buf);
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory reading the file");
      }
      buf = nb;
      cap *= 2;
    }
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (got == 0 || n < cap) {
      if (ferror(f)) {
        int e = errno;
        free(buf);
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_IO, 0, (long long)n, "read failed: %s",
                          strerror(e ? e : EIO));
      }
      if (feof(f)) break;
    }
  }
  if (!is_stdin) fclose(f);
  /* the content's own signature wins over the extension; text without one
   * and without a known extension is sniffed (docs/formats.md) */
  bsurf_format declared = bsurf_format_detect(buf, n);
  if (declared != BSURF_FORMAT_UNKNOWN &&
      !(declared == BSURF_FORMAT_OFF && format == BSURF_FORMAT_OBJ))
    format = declared;
  else if (format == BSURF_FORMAT_UNKNOWN) {
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    if (dot && dot != base) { /* an extension bootsurf does not know, and no signature */
      free(buf);
      return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1,
                        "%s; the content is not PLY, PCD, LAS or OFF either", k_unknown_ext);
    }
    format = sniff_text(buf, n); /* no extension (or standard input): text */
  }
  bsurf_status st = bsurf_read_buffer(buf, n, format, cloud, err);
  free(buf);
  return st;
}

/* The header check of bsurf_read_header(_buffer); *ascii_short: ascii data
 * too short for the header's counts (the whole file, read, names the line). */
static bsurf_status header_check(const void *data, size_t size, uint64_t file_size,
                                 bsurf_format format, uint64_t *points, int *ascii_short,
                                 bsurf_failure *err) {
  clear_error(err);
  *points = 0;
  *ascii_short = 0;
  if (format != BSURF_FORMAT_PLY) return BSURF_OK;
  if (!data && size) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no data given");
  unsigned long long n = 0;
  bsurf_status st =
      io_ply_probe(data ? (const char *)data : "", size, file_size, &n, ascii_short, err);
  if (st != BSURF_OK && err && !err->message[0])
    bsurf_fail(err, st, err->line, err->byte, "%s", bsurf_strerror(st));
  *points = n;
  return st;
}

bsurf_status bsurf_read_header_buffer(const void *data, size_t size, uint64_t file_size,
                                      bsurf_format format, uint64_t *points, bsurf_failure *err) {
  int ascii_short = 0;
  bsurf_status st = header_check(data, size, file_size, format, points, &ascii_short, err);
  if (st != BSURF_OK && ascii_short && file_size == size) {
    /* the whole file is here: the reader names the line where the data ends
     * (it stores no vertex when the data cannot hold the header's counts) */
    bsurf_cloud unused;
    st = bsurf_read_buffer(data, size, format, &unused, err);
    bsurf_cloud_free(&unused);
    if (st == BSURF_OK) st = BSURF_ERR_PARSE; /* not reached: the check is the reader's own */
  }
  return st;
}

/* The end of a PLY header ("end_header" and the bytes of its line break) is
 * in buf[0..n). */
static int has_header_end(const char *buf, size_t n, size_t from) {
  static const char word[] = "end_header";
  const size_t wl = sizeof word - 1;
  for (size_t i = from; i + wl + 2 <= n; i++)
    if (buf[i] == 'e' && i > 0 && (buf[i - 1] == '\n' || buf[i - 1] == '\r') &&
        memcmp(buf + i, word, wl) == 0)
      return 1;
  return 0;
}

bsurf_status bsurf_read_header(const char *path, uint64_t *points, bsurf_failure *err) {
  clear_error(err);
  *points = 0;
  if (!path) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path given");
  bsurf_format format = bsurf_format_from_path(path);
  if (format != BSURF_FORMAT_PLY) return BSURF_OK;
  FILE *f = fopen(path, "rb");
  if (!f) return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open: %s", strerror(errno));
  struct stat sb;
  if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode)) {
    fclose(f); /* pipes and devices: read whole by bsurf_read, checked there */
    return BSURF_OK;
  }
  /* read until the header's end (any size: a header of 100,000 properties
   * is 2.5 MB), doubling the buffer */
  size_t cap = 1 << 16, n = 0;
  char *buf = NULL;
  bsurf_status st = BSURF_OK;
  for (;;) {
    char *nb = realloc(buf, cap);
    if (!nb) {
      st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory reading the header");
      break;
    }
    buf = nb;
    size_t from = n > 16 ? n - 16 : 0;
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (ferror(f)) {
      st = bsurf_fail(err, BSURF_ERR_IO, 0, (long long)n, "read failed: %s",
                      strerror(errno ? errno : EIO));
      break;
    }
    if (got == 0 || feof(f) || has_header_end(buf, n, from)) break;
    if (cap > (size_t)-1 / 4) break;
    cap *= 2;
  }
  fclose(f);
  int ascii_short = 0;
  if (st == BSURF_OK)
    st = header_check(buf, n, (uint64_t)sb.st_size, format, points, &ascii_short, err);
  free(buf);
  if (st != BSURF_OK && ascii_short) {
    /* ascii data too short for its header: the file, read whole, names the
     * line where the data ends (the reader stores no vertex then) */
    bsurf_cloud unused;
    st = bsurf_read(path, &unused, err);
    bsurf_cloud_free(&unused);
    if (st == BSURF_OK) st = BSURF_ERR_PARSE; /* not reached: the check is the reader's own */
  }
  return st;
}

/* ------------------------------------------------------------------------ */
/* Writing                                                                   */
/* ------------------------------------------------------------------------ */

static bsurf_status check_cloud(const bsurf_cloud *cloud, bsurf_failure *err) {
  if (cloud->point_count && !cloud->xyz)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "the cloud has no coordinates");
  for (size_t i = 0; i < cloud->field_count; i++)
    if (cloud->point_count && !cloud->fields[i].values)
      return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "field '%s' has no values",
                        cloud->fields[i].name);
  if (cloud->face_count && !cloud->faces)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "the cloud has no face array");
  for (size_t i = 0; i < 3 * cloud->face_count; i++)
    if (cloud->faces[i] >= cloud->point_count)
      return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                        "face %zu refers to point %lu but the cloud has %zu points", i / 3,
                        (unsigned long)cloud->faces[i], cloud->point_count);
  return BSURF_OK;
}

/* The fields of `view` (an array of field_count + 1) from the cloud's, with
 * float32 types (opts->float32) and PLY names for a viewer (opts->ply_names:
 * docs/formats.md). */
static bsurf_status write_view(bsurf_cloud *view, const bsurf_cloud *cloud,
                               const bsurf_write_options *opts, bsurf_format format,
                               bsurf_failure *err) {
  bsurf_field *fields = view->fields;
  if (cloud->field_count) memcpy(fields, cloud->fields, cloud->field_count * sizeof *fields);
  if (opts->float32) {
    if (view->xyz_type == BSURF_FLOAT64) view->xyz_type = BSURF_FLOAT32;
    if (view->normal_type == BSURF_FLOAT64) view->normal_type = BSURF_FLOAT32;
    for (size_t i = 0; i < cloud->field_count; i++)
      if (fields[i].type == BSURF_FLOAT64) fields[i].type = BSURF_FLOAT32;
  }
  if (format != BSURF_FORMAT_PLY) return BSURF_OK;
  if (opts->ply_names == BSURF_PLY_NAMES_CLOUDCOMPARE) {
    /* CloudCompare loads a vertex property as a scalar field only when its
     * name contains "scal" (or "intensity", "gray", "grey"), and removes a
     * leading "scalar_" when it does */
    for (size_t i = 0; i < cloud->field_count; i++) {
      char name[2 * BSURF_FIELD_NAME_MAX];
      snprintf(name, sizeof name, "scalar_%s", fields[i].name);
      if (strlen(name) >= BSURF_FIELD_NAME_MAX)
        return bsurf_fail(
            err, BSURF_ERR_INVALID_ARG, 0, -1,
            "field '%s': with the prefix scalar_ the name is longer than %d characters",
            fields[i].name, BSURF_FIELD_NAME_MAX - 1);
      memcpy(fields[i].name, name, strlen(name) + 1);
    }
  } else if (opts->ply_names == BSURF_PLY_NAMES_MESHLAB && cloud->field_count &&
             !bsurf_cloud_field(cloud, "quality")) {
    /* MeshLab (vcglib's PLY importer) keeps one per-vertex scalar, "quality" */
    fields[cloud->field_count] = fields[0];
    snprintf(fields[cloud->field_count].name, BSURF_FIELD_NAME_MAX, "quality");
    fields[cloud->field_count].type = BSURF_FLOAT32;
    view->field_count = cloud->field_count + 1;
  }
  return BSURF_OK;
}

bsurf_status bsurf_write(const char *path, const bsurf_cloud *cloud,
                         const bsurf_write_options *opts, bsurf_failure *err) {
  clear_error(err);
  if (!path || !cloud)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path or no cloud given");
  bsurf_format format = opts && opts->format ? opts->format : bsurf_format_from_path(path);
  /* a FIFO or device without an extension (-o /dev/null) gets PLY, the
   * format that keeps everything */
  if (format == BSURF_FORMAT_UNKNOWN && bsurf_output_is_stream(path)) format = BSURF_FORMAT_PLY;
  if (format == BSURF_FORMAT_UNKNOWN)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1, "%s",
                      strcmp(path, "-") == 0 ? "standard output needs a format (--format)"
                                             : k_unknown_ext);
  bsurf_status st = check_cloud(cloud, err);
  if (st != BSURF_OK) return st;
  /* --float32 and --ply-names: a view of the cloud with other field types and
   * names (the values are shared, not copied) */
  bsurf_cloud view = *cloud;
  bsurf_field *fields = NULL;
  if (opts && (opts->float32 || (format == BSURF_FORMAT_PLY && opts->ply_names))) {
    fields = bsurf_alloc_array(cloud->field_count + 1, sizeof *fields);
    if (!fields) return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
    view.fields = fields;
    st = write_view(&view, cloud, opts, format, err);
  }
  if (st == BSURF_OK && bsurf_format_keeps_fields(format)) st = bsurf_io_ply_check(&view, err);
  if (st == BSURF_OK && format == BSURF_FORMAT_LAS) st = bsurf_io_las_check(&view, err);
  if (st != BSURF_OK) {
    free(fields);
    return st;
  }

  bsurf_atomic_file af;
  st = bsurf_atomic_open(&af, path, err);
  if (st != BSURF_OK) {
    free(fields);
    return st;
  }
  io_writer w = {af.f, 0, 0};
  int ascii = opts && opts->ascii;
  switch (format) {
  case BSURF_FORMAT_PLY: st = bsurf_io_write_ply(&w, &view, ascii, err); break;
  case BSURF_FORMAT_OFF: st = bsurf_io_write_off(&w, &view, err); break;
  case BSURF_FORMAT_OBJ: st = bsurf_io_write_obj(&w, &view, err); break;
  case BSURF_FORMAT_PCD: st = bsurf_io_write_pcd(&w, &view, ascii, err); break;
  case BSURF_FORMAT_LAS: st = bsurf_io_write_las(&w, &view, opts && opts->las_legacy, err); break;
  case BSURF_FORMAT_CSV: {
    const char *dot = strrchr(path, '.');
    st = bsurf_io_write_csv(&w, &view, dot && ext_is(dot + 1, "asc"), err);
    break;
  }
  case BSURF_FORMAT_XYZ:
  case BSURF_FORMAT_UNKNOWN:
  default: st = bsurf_io_write_xyz(&w, &view, err); break;
  }
  free(fields);
  return bsurf_atomic_close(&af, st, w.failed ? (w.err_no ? w.err_no : EIO) : 0, err);
}

/* ------------------------------------------------------------------------ */
/* Buffered text output                                                      */
/* ------------------------------------------------------------------------ */

#define IO_OBUF_CAP ((size_t)1 << 16)
#define IO_VALUE_MAX 64 /* longest formatted value, with room to spare */

bsurf_status io_obuf_init(io_obuf *b, io_writer *w) {
  b->w = w;
  b->n = 0;
  b->cap = IO_OBUF_CAP;
  b->buf = malloc(b->cap);
  return b->buf ? BSURF_OK : BSURF_ERR_NOMEM;
}

void io_obuf_flush(io_obuf *b) {
  io_write_bytes(b->w, b->buf, b->n);
  b->n = 0;
}

void io_obuf_done(io_obuf *b) {
  if (b->buf) io_obuf_flush(b);
  free(b->buf);
  b->buf = NULL;
}

static void obuf_room(io_obuf *b, size_t n) {
  if (b->cap - b->n < n) io_obuf_flush(b);
}

void io_obuf_str(io_obuf *b, const char *s) {
  size_t n = strlen(s);
  if (n > b->cap / 2) {
    io_obuf_flush(b);
    io_write_bytes(b->w, s, n);
    return;
  }
  obuf_room(b, n);
  memcpy(b->buf + b->n, s, n);
  b->n += n;
}

void io_obuf_char(io_obuf *b, char c) {
  obuf_room(b, 1);
  b->buf[b->n++] = c;
}

void io_obuf_value(io_obuf *b, double v, bsurf_type type) {
  obuf_room(b, IO_VALUE_MAX);
  b->n += io_format_value(b->buf + b->n, IO_VALUE_MAX, v, type);
}

void io_obuf_uint(io_obuf *b, unsigned long long v) {
  char tmp[24];
  size_t n = 0;
  do {
    tmp[n++] = (char)('0' + v % 10);
    v /= 10;
  } while (v);
  obuf_room(b, n);
  while (n)
    b->buf[b->n++] = tmp[--n];
}
