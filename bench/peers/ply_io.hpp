// ply_io.hpp — the minimal PLY reader/writer shared by the C++ peer programs
// (bench/peers/normals_pcl.cpp, normals_cgal.cpp). Header-only, C++17.
//
// Reads the vertex positions of a PLY file as bootsurf writes it: format
// binary_little_endian (also binary_big_endian and ascii), an element "vertex"
// with scalar properties x y z of any PLY type (float/double/int...), other
// scalar vertex properties skipped. Elements after "vertex" (faces) are not
// read. Writes x y z nx ny nz as binary little-endian doubles, the layout
// bootsurf's own readers and `bootsurf eval` accept.
//
// File I/O is never part of a peer's timing; the reader works in blocks of rows
// so that a peer's peak RSS holds no copy of the whole file.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace plyio {

struct Prop {
  std::string name;
  int size = 0;  // bytes
  char kind = 0; // 'i' signed, 'u' unsigned, 'f' float
};

static inline bool type_of(const std::string &t, Prop &p) {
  static const struct {
    const char *n;
    int s;
    char k;
  } tab[] = {{"char", 1, 'i'},  {"int8", 1, 'i'},    {"uchar", 1, 'u'},  {"uint8", 1, 'u'},
             {"short", 2, 'i'}, {"int16", 2, 'i'},   {"ushort", 2, 'u'}, {"uint16", 2, 'u'},
             {"int", 4, 'i'},   {"int32", 4, 'i'},   {"uint", 4, 'u'},   {"uint32", 4, 'u'},
             {"float", 4, 'f'}, {"float32", 4, 'f'}, {"double", 8, 'f'}, {"float64", 8, 'f'}};
  for (const auto &e : tab)
    if (t == e.n) {
      p.size = e.s;
      p.kind = e.k;
      return true;
    }
  return false;
}

static inline double decode(const unsigned char *b, const Prop &p, bool swap) {
  unsigned char t[8];
  for (int i = 0; i < p.size; i++)
    t[i] = swap ? b[p.size - 1 - i] : b[i];
  switch (p.kind) {
  case 'f':
    if (p.size == 4) {
      float f;
      std::memcpy(&f, t, 4);
      return f;
    } else {
      double d;
      std::memcpy(&d, t, 8);
      return d;
    }
  case 'i':
    if (p.size == 1) {
      int8_t v;
      std::memcpy(&v, t, 1);
      return v;
    }
    if (p.size == 2) {
      int16_t v;
      std::memcpy(&v, t, 2);
      return v;
    }
    {
      int32_t v;
      std::memcpy(&v, t, 4);
      return v;
    }
  default:
    if (p.size == 1) return t[0];
    if (p.size == 2) {
      uint16_t v;
      std::memcpy(&v, t, 2);
      return v;
    }
    {
      uint32_t v;
      std::memcpy(&v, t, 4);
      return v;
    }
  }
}

static inline bool read_columns(const std::string &path, const std::vector<std::string> &names,
                                std::vector<double> &cols);

// Reads the vertex positions: xyz gets 3 * n doubles. Throws std::runtime_error.
static inline void read_xyz(const std::string &path, std::vector<double> &xyz) {
  if (!read_columns(path, {"x", "y", "z"}, xyz)) throw std::runtime_error(path + ": no x y z");
}

// Writes x y z nx ny nz (binary little-endian doubles); n = xyz.size() / 3.
static inline void write_xyz_normals(const std::string &path, const std::vector<double> &xyz,
                                     const std::vector<double> &nrm, const std::string &comment) {
  const size_t n = xyz.size() / 3;
  if (nrm.size() != xyz.size()) throw std::runtime_error("write: normals size mismatch");
  const std::string tmp = path + ".tmp";
  FILE *f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw std::runtime_error(path + ": cannot write");
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\ncomment %s\nelement vertex %zu\n"
               "property double x\nproperty double y\nproperty double z\n"
               "property double nx\nproperty double ny\nproperty double nz\nend_header\n",
               comment.c_str(), n);
  std::vector<double> row(6 * 4096);
  bool ok = true;
  for (size_t s = 0; s < n && ok; s += 4096) {
    const size_t m = n - s < 4096 ? n - s : 4096;
    for (size_t r = 0; r < m; r++)
      for (int c = 0; c < 3; c++) {
        row[6 * r + c] = xyz[3 * (s + r) + c];
        row[6 * r + 3 + c] = nrm[3 * (s + r) + c];
      }
    // little-endian host assumed (x86-64, aarch64); checked at startup by the peers
    ok = std::fwrite(row.data(), sizeof(double), 6 * m, f) == 6 * m;
  }
  if (std::fclose(f) != 0 || !ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot write");
  }
}

// Reads the named scalar vertex properties (e.g. {"nx","ny","nz"}) into cols,
// n * names.size() doubles, row-major. Returns false (cols empty) when one of
// them is missing; throws std::runtime_error on a malformed file. ascii and
// binary (either byte order), read in blocks of rows so that the peers' peak
// RSS does not count a copy of the file.
static inline bool read_columns(const std::string &path, const std::vector<std::string> &names,
                                std::vector<double> &cols) {
  cols.clear();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::string line, format;
  std::getline(in, line);
  if (line.rfind("ply", 0) != 0) throw std::runtime_error(path + ": not a PLY file");
  size_t n = 0;
  bool in_vertex = false, vertex_seen = false;
  std::vector<Prop> props;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string w;
    ls >> w;
    if (w == "format")
      ls >> format;
    else if (w == "element") {
      std::string name;
      ls >> name;
      if (name == "vertex") {
        if (vertex_seen) throw std::runtime_error(path + ": two vertex elements");
        ls >> n;
        in_vertex = vertex_seen = true;
      } else {
        // the vertex data must come first in the body
        if (!vertex_seen) throw std::runtime_error(path + ": an element before vertex");
        in_vertex = false;
      }
    } else if (w == "property" && in_vertex) {
      std::string t, name;
      ls >> t;
      if (t == "list") throw std::runtime_error(path + ": list property in vertex");
      ls >> name;
      Prop p;
      p.name = name;
      if (!type_of(t, p)) throw std::runtime_error(path + ": unknown type " + t);
      props.push_back(p);
    } else if (w == "end_header")
      break;
  }
  const size_t m = names.size();
  std::vector<int> idx(m, -1);
  std::vector<size_t> off(props.size());
  size_t stride = 0;
  for (size_t i = 0; i < props.size(); i++) {
    off[i] = stride;
    stride += props[i].size;
    for (size_t c = 0; c < m; c++)
      if (props[i].name == names[c]) idx[c] = (int)i;
  }
  for (size_t c = 0; c < m; c++)
    if (idx[c] < 0) return false;
  cols.resize(n * m);
  if (format == "ascii") {
    std::vector<double> v(props.size());
    for (size_t r = 0; r < n; r++) {
      for (size_t i = 0; i < props.size(); i++)
        if (!(in >> v[i])) throw std::runtime_error(path + ": short ascii data");
      for (size_t c = 0; c < m; c++)
        cols[m * r + c] = v[idx[c]];
    }
    return true;
  }
  const uint16_t one = 1;
  const bool host_le = *(const unsigned char *)&one == 1;
  bool swap;
  if (format == "binary_little_endian")
    swap = !host_le;
  else if (format == "binary_big_endian")
    swap = host_le;
  else
    throw std::runtime_error(path + ": unknown format " + format);
  const size_t block = 65536;
  std::vector<unsigned char> buf(stride * (n < block ? n : block));
  for (size_t s = 0; s < n; s += block) {
    const size_t b = n - s < block ? n - s : block;
    in.read((char *)buf.data(), (std::streamsize)(stride * b));
    if ((size_t)in.gcount() != stride * b) throw std::runtime_error(path + ": short binary data");
    for (size_t r = 0; r < b; r++)
      for (size_t c = 0; c < m; c++)
        cols[m * (s + r) + c] = decode(buf.data() + r * stride + off[idx[c]], props[idx[c]], swap);
  }
  return true;
}

// Writes x y z (doubles), then nx ny nz (doubles) when nrm is not empty, then
// every extra column as a float property; binary little-endian, atomic (temporary
// file + rename). n = xyz.size() / 3; each extra column holds n values.
struct Extra {
  std::string name;
  std::vector<float> values;
};
static inline void write_points(const std::string &path, const std::vector<double> &xyz,
                                const std::vector<double> &nrm, const std::vector<Extra> &extra,
                                const std::string &comment) {
  const size_t n = xyz.size() / 3;
  if (!nrm.empty() && nrm.size() != xyz.size())
    throw std::runtime_error("write: normals size mismatch");
  for (const Extra &e : extra)
    if (e.values.size() != n)
      throw std::runtime_error("write: column " + e.name + " size mismatch");
  const std::string tmp = path + ".tmp";
  FILE *f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw std::runtime_error(path + ": cannot write");
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\ncomment %s\nelement vertex %zu\n"
               "property double x\nproperty double y\nproperty double z\n",
               comment.c_str(), n);
  if (!nrm.empty()) std::fprintf(f, "property double nx\nproperty double ny\nproperty double nz\n");
  for (const Extra &e : extra)
    std::fprintf(f, "property float %s\n", e.name.c_str());
  std::fprintf(f, "end_header\n");
  const size_t row_bytes = 8 * (nrm.empty() ? 3 : 6) + 4 * extra.size();
  std::vector<unsigned char> buf(row_bytes * 4096);
  bool ok = true;
  for (size_t s = 0; s < n && ok; s += 4096) {
    const size_t m = n - s < 4096 ? n - s : 4096;
    unsigned char *p = buf.data();
    for (size_t r = 0; r < m; r++) { // little-endian host (x86-64, aarch64)
      std::memcpy(p, &xyz[3 * (s + r)], 24);
      p += 24;
      if (!nrm.empty()) {
        std::memcpy(p, &nrm[3 * (s + r)], 24);
        p += 24;
      }
      for (const Extra &e : extra) {
        std::memcpy(p, &e.values[s + r], 4);
        p += 4;
      }
    }
    ok = std::fwrite(buf.data(), 1, row_bytes * m, f) == row_bytes * m;
  }
  if (std::fclose(f) != 0 || !ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot write");
  }
}

} // namespace plyio
