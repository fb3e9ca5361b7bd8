#include "app/lammps_data.hpp"

#include "app/scenario.hpp"
#include "io/toml_reader.hpp"

#include <lgvi/error.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <numeric>
#include <optional>
#include <string_view>
#include <tuple>
#include <unordered_map>

namespace lgvi::app {
namespace {

/// FNV-1a, 64 bits (file_checksum).
struct Fnv1a {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  void add(const char* bytes, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      h ^= static_cast<unsigned char>(bytes[i]);
      h *= 0x100000001b3ULL;
    }
  }
  std::string hex() const { return fmt::format("{:016x}", h); }
};

/// The kinds of a data file's bodies. A body joins an earlier kind when its
/// balls, in the same order (increasing atom ID), have that kind's types,
/// masses and radii, and a rotation S (Kabsch: the proper rotation that fits
/// them best) takes its principal-axes positions to the kind's, each to
/// 1e-12 of the kind's size: identical molecules differ only by the sign
/// and, for equal moments, the choice of their principal axes, and by
/// round-off. Its state is then the kind's: the attitude q S^T, the body
/// momentum S w. A file whose molecules differ beyond that (coordinates of
/// a few digits) gives each its own kind; a species is compared with its
/// first `candidates` kinds only, so that set-up stays O(N).
class KindMatcher {
 public:
  static constexpr std::size_t candidates = 8;

  /// The kind of `body` (principal axes) with state `s`, changed to the kind's frame if it joins one.
  std::uint32_t add(RigidBody body, RigidBodyState& s) {
    std::vector<std::uint32_t>& species = by_species_[species_hash(body)];
    for (const std::uint32_t k : species) {
      const std::optional<Matrix3<double>> turn = fit(kinds[k], body);
      if (!turn) continue;
      s.q = s.q * S3d::from_rotation_matrix(*turn).inverse();
      s.w = kinds[k].admissible_momentum(*turn * s.w);
      return k;
    }
    kinds.push_back(std::move(body));
    const auto k = static_cast<std::uint32_t>(kinds.size() - 1);
    if (species.size() < candidates) species.push_back(k);
    return k;
  }

  std::vector<RigidBody> kinds;

 private:
  static std::uint64_t species_hash(const RigidBody& body) {
    Fnv1a h;
    auto add = [&h](const auto& v) { h.add(reinterpret_cast<const char*>(&v), sizeof v); };
    add(body.balls().size());
    for (const Ball& b : body.balls()) {
      add(b.type);
      add(b.mass);
      add(b.radius);
    }
    return h.h;
  }

  /// S with S p_i = kind's p_i for every ball to 1e-12 of the kind's size, if the species agree.
  static std::optional<Matrix3<double>> fit(const RigidBody& kind, const RigidBody& body) {
    const std::vector<Ball>& a = kind.balls();
    const std::vector<Ball>& b = body.balls();
    if (a.size() != b.size()) return std::nullopt;
    double size = 0.0;
    Matrix3<double> h = Matrix3<double>::Zero();
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (a[i].type != b[i].type || a[i].mass != b[i].mass || a[i].radius != b[i].radius) return std::nullopt;
      size = std::max(size, a[i].position.norm());
      h += a[i].position * b[i].position.transpose();
    }
    if (size == 0.0) return Matrix3<double>::Identity();  // a point (one atom)
    const Eigen::JacobiSVD<Matrix3<double>> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Matrix3<double> d = Matrix3<double>::Identity();
    d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
    const Matrix3<double> turn = svd.matrixU() * d * svd.matrixV().transpose();
    for (std::size_t i = 0; i < a.size(); ++i)
      if (!((turn * b[i].position - a[i].position).norm() <= 1e-12 * size)) return std::nullopt;
    return turn;
  }

  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> by_species_;
};

/// The file read line by line: comments ('#' to the end) cut off and kept,
/// the rest split at white space; messages name the file and the line.
class DataLines {
 public:
  explicit DataLines(const std::string& path) : path_(path), in_(path, std::ios::binary) {
    if (!in_) throw InvalidInput(printable(path) + ": cannot open the LAMMPS data file ([import] lammps_data is "
                                                   "relative to the scenario file)");
  }

  /// The next line; false at the end of the file.
  bool next() {
    if (!std::getline(in_, text_)) return false;
    hash_.add(text_.data(), text_.size());
    if (!in_.eof()) hash_.add("\n", 1);  // getline consumed one (at the end it stops without)
    ++number_;
    if (!text_.empty() && text_.back() == '\r') text_.pop_back();
    const std::size_t hash = text_.find('#');
    comment_ = hash == std::string::npos ? std::string() : text_.substr(hash + 1);
    if (hash != std::string::npos) text_.resize(hash);
    tokens_.clear();
    std::size_t i = 0;
    while (i < text_.size()) {
      while (i < text_.size() && std::isspace(static_cast<unsigned char>(text_[i]))) ++i;
      const std::size_t start = i;
      while (i < text_.size() && !std::isspace(static_cast<unsigned char>(text_[i]))) ++i;
      if (i > start) tokens_.emplace_back(text_.data() + start, i - start);
    }
    return true;
  }

  /// file_checksum of the whole file: the lines read so far and the rest.
  std::string checksum() {
    while (next()) {
    }
    return hash_.hex();
  }

  const std::vector<std::string_view>& tokens() const { return tokens_; }
  bool blank() const { return tokens_.empty(); }
  /// A section's name ("Atoms", "Pair Coeffs"): a line that begins with a letter.
  bool section() const { return !blank() && std::isalpha(static_cast<unsigned char>(tokens_[0][0])); }
  std::string words(std::size_t from = 0) const {
    std::string s;
    for (std::size_t k = from; k < tokens_.size(); ++k) {
      if (k > from) s.push_back(' ');
      s.append(tokens_[k]);
    }
    return s;
  }
  /// The comment's first word ("Atoms # full" gives "full").
  std::string comment_word() const {
    std::size_t i = 0;
    while (i < comment_.size() && std::isspace(static_cast<unsigned char>(comment_[i]))) ++i;
    std::size_t j = i;
    while (j < comment_.size() && !std::isspace(static_cast<unsigned char>(comment_[j]))) ++j;
    return comment_.substr(i, j - i);
  }

  double number(std::size_t k, const char* what) const {
    double v = 0.0;
    std::string_view t = tokens_[k];
    if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);  // (from_chars takes no '+'; LAMMPS does)
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size() || !std::isfinite(v))
      fail(fmt::format("{} must be a finite number, got \"{}\"", what, printable(t)));
    return v;
  }
  std::int64_t integer(std::size_t k, const char* what) const {
    std::int64_t v = 0;
    std::string_view t = tokens_[k];
    if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size())
      fail(fmt::format("{} must be an integer, got \"{}\"", what, printable(t)));
    return v;
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw InvalidInput(fmt::format("{}:{}: {}", printable(path_), number_, what));
  }

 private:
  std::string path_;
  std::ifstream in_;
  std::string text_, comment_;
  std::vector<std::string_view> tokens_;
  long number_ = 0;
  Fnv1a hash_;  ///< of the bytes read (checksum)
};

/// The counted header lines of a data file (LAMMPS's read_data), by their words.
bool is_counted_header(const std::string& keyword) {
  static constexpr std::string_view known[] = {
      "atoms",        "bonds",          "angles",         "dihedrals",       "impropers",
      "atom types",   "bond types",     "angle types",    "dihedral types",  "improper types",
      "ellipsoids",   "lines",          "triangles",      "bodies",          "extra bond per atom",
      "extra angle per atom", "extra dihedral per atom", "extra improper per atom", "extra special per atom"};
  return std::find(std::begin(known), std::end(known), keyword) != std::end(known);
}

/// The sections of a data file that make no difference to rigid bodies (LAMMPS's read_data's names).
bool is_skipped_section(const std::string& name) {
  static constexpr std::string_view known[] = {
      "Bonds", "Angles", "Dihedrals", "Impropers", "Pair Coeffs", "PairIJ Coeffs", "Bond Coeffs", "Angle Coeffs",
      "Dihedral Coeffs", "Improper Coeffs", "BondBond Coeffs", "BondAngle Coeffs", "MiddleBondTorsion Coeffs",
      "EndBondTorsion Coeffs", "AngleTorsion Coeffs", "AngleAngleTorsion Coeffs", "BondBond13 Coeffs",
      "AngleAngle Coeffs", "Ellipsoids", "Lines", "Triangles", "Bodies"};
  return std::find(std::begin(known), std::end(known), name) != std::end(known);
}

struct Atom {
  std::int64_t id = 0, molecule = 0;
  int type = 0;
  Vector3<double> x = Vector3<double>::Zero();  ///< unwrapped: x + image * L
  Vector3<double> v = Vector3<double>::Zero();
};

/// The Atoms section's columns: id mol type [q] x y z [ix iy iz].
struct AtomColumns {
  std::size_t position = 3;  ///< the column of x
  bool images = false;
};

AtomColumns atom_columns(const DataLines& in, const std::string& style) {
  const std::size_t n = in.tokens().size();
  const std::size_t base = style == "full" ? 7 : 6;
  if (n != base && n != base + 3)
    in.fail(fmt::format("an Atoms line of atom_style {} has {} or {} columns, this one {}", style, base, base + 3, n));
  return {base - 3, n == base + 3};
}

}  // namespace

LammpsDataBodies read_lammps_data(const std::string& path, const std::vector<double>& radius,
                                  const std::array<bool, 3>& periodic, const std::string& atom_style) {
  DataLines in(path);
  const std::string file = printable(path);
  LammpsDataBodies out;
  out.lower = Vector3<double>::Constant(-0.5);  // LAMMPS's defaults
  out.upper = Vector3<double>::Constant(0.5);
  std::optional<std::int64_t> header_atoms;
  std::optional<std::int64_t> header_types;
  if (!in.next()) throw InvalidInput(file + ": empty; a LAMMPS data file begins with a title line");
  // The header: "N atoms", "N atom types", "xlo xhi" ..., until the first section.
  bool more = in.next();
  for (; more && !in.section(); more = in.next()) {
    if (in.blank()) continue;
    std::size_t numbers = 0;
    while (numbers < in.tokens().size() &&
           !std::isalpha(static_cast<unsigned char>(in.tokens()[numbers][0])))
      ++numbers;
    const std::string keyword = in.words(numbers);
    if (keyword == "atoms" && numbers == 1) {
      header_atoms = in.integer(0, "the number of atoms");
      if (*header_atoms < 1 || *header_atoms > 100000000) in.fail("the number of atoms must be in [1, 10^8]");
    } else if (keyword == "atom types" && numbers == 1) {
      header_types = in.integer(0, "the number of atom types");
      if (*header_types < 1 || *header_types > max_site_types)
        in.fail(fmt::format("the number of atom types must be in [1, {}]", max_site_types));
    } else if ((keyword == "xlo xhi" || keyword == "ylo yhi" || keyword == "zlo zhi") && numbers == 2) {
      const int k = keyword[0] - 'x';
      out.lower(k) = in.number(0, "the box's lower bound");
      out.upper(k) = in.number(1, "the box's upper bound");
      if (!(out.upper(k) > out.lower(k))) in.fail(keyword + ": the upper bound must exceed the lower");
    } else if (keyword == "xy xz yz" && numbers == 3) {
      for (std::size_t k = 0; k < 3; ++k)
        if (in.number(k, "a tilt factor") != 0.0)
          in.fail("a triclinic box (xy xz yz not all 0) is not supported yet: lgvi's boxes are orthogonal");
    } else if (!is_counted_header(keyword) || numbers != 1) {
      in.fail("not a header line of a LAMMPS data file (\"N atoms\", \"N atom types\", \"xlo xhi\", ... each with its "
              "count of numbers), nor a section name: \"" + printable(in.words()) + "\"");
    }
    // The other counted lines (bonds, angles, their types, extra ... per
    // atom) say nothing about rigid bodies: their sections are skipped below.
  }
  if (!header_atoms) throw InvalidInput(file + ": the header has no \"N atoms\" line");
  if (!header_types) throw InvalidInput(file + ": the header has no \"N atom types\" line");
  const auto atoms = static_cast<std::size_t>(*header_atoms);
  const auto types = static_cast<std::size_t>(*header_types);
  out.atoms = *header_atoms;
  out.atom_types = static_cast<int>(types);
  if (!radius.empty() && radius.size() != 1 && radius.size() != types)
    throw InvalidInput(fmt::format("{}: [import] radius has {} entries; give one radius, or one per atom type ({})",
                                   file, radius.size(), types));

  std::vector<double> mass(types + 1, 0.0);
  std::vector<Atom> atom;
  std::unordered_map<std::int64_t, std::size_t> index;  // atom ID -> atom
  bool have_masses = false, have_velocities = false;
  const Vector3<double> length = out.upper - out.lower;
  // Reads the `count` data lines of the section just named, calling row() on each.
  auto section_rows = [&](std::size_t count, const std::string& name, const char* counted, auto&& row) {
    for (std::size_t k = 0; k < count;) {
      if (!in.next())
        throw InvalidInput(fmt::format("{}: the {} section ends after {} lines; the header says {} {}", file, name, k,
                                       count, counted));
      if (in.blank()) continue;
      if (in.section())
        in.fail(fmt::format("the {} section has {} lines before \"{}\"; the header says {} {}", name, k,
                            printable(in.words()), count, counted));
      row();
      ++k;
    }
    more = in.next();
  };
  while (more) {
    if (in.blank()) {
      more = in.next();
      continue;
    }
    if (!in.section())
      in.fail("a line of numbers outside any section: the section before it has more lines than its count in the "
              "header");
    const std::string name = in.words();
    if (name == "Atoms") {
      if (!atom.empty()) in.fail("a second Atoms section");
      // The style: the section's comment (LAMMPS's write_data writes it) or [import] atom_style; never
      // guessed from the columns (charge, sphere or dipole lines have the column counts of molecular or full).
      std::string style = in.comment_word();
      if (style.empty() && atom_style.empty())
        in.fail("the Atoms section names no atom_style (\"Atoms # full\"); give it there or as [import] atom_style "
                "(\"full\", \"molecular\", \"bond\" or \"angle\")");
      if (!style.empty() && !atom_style.empty() && style != atom_style)
        in.fail("the Atoms section is of atom_style " + printable(style) + ", [import] atom_style says " + atom_style);
      if (style.empty()) style = atom_style;
      if (style != "full" && style != "molecular" && style != "bond" && style != "angle")
        in.fail("atom_style " + printable(style) +
                " has no molecule IDs; lgvi makes rigid bodies of the molecules of atom_style full, molecular, bond "
                "or angle");
      if (style == "bond" || style == "angle") style = "molecular";
      atom.reserve(atoms);
      index.reserve(atoms);
      std::optional<AtomColumns> cols;
      section_rows(atoms, "Atoms", "atoms", [&] {
        if (!cols) cols = atom_columns(in, style);
        if (in.tokens().size() != cols->position + 3 + (cols->images ? 3 : 0))
          in.fail(fmt::format("an Atoms line of atom_style {} has {} columns, this one {}", style,
                              cols->position + 3 + (cols->images ? 3 : 0), in.tokens().size()));
        Atom a;
        a.id = in.integer(0, "the atom ID");
        if (a.id < 1) in.fail(fmt::format("the atom ID must be >= 1, got {}", a.id));
        a.molecule = in.integer(1, "the molecule ID");
        if (a.molecule < 0) in.fail(fmt::format("the molecule ID must be >= 0, got {}", a.molecule));
        const std::int64_t type = in.integer(2, "the atom type");
        if (type < 1 || type > static_cast<std::int64_t>(types))
          in.fail(fmt::format("atom type {} is not in 1..{} (the header's atom types)", type, types));
        a.type = static_cast<int>(type);
        for (int k = 0; k < 3; ++k) {
          a.x(k) = in.number(cols->position + static_cast<std::size_t>(k), "a coordinate");
          if (cols->images) {
            const std::int64_t image = in.integer(cols->position + 3 + static_cast<std::size_t>(k), "an image flag");
            if (std::abs(image) > (std::int64_t{1} << 20)) in.fail("an image flag beyond 2^20");
            if (image != 0 && !periodic[static_cast<std::size_t>(k)])
              in.fail(fmt::format("atom {} has image flag {} along {}, which [import] periodic makes open; an open "
                                  "axis has no images (LAMMPS resets them to 0: write 0, or make the axis periodic)",
                                  a.id, image, "xyz"[k]));
            a.x(k) += static_cast<double>(image) * length(k);
          }
        }
        if (!index.emplace(a.id, atom.size()).second) in.fail(fmt::format("atom ID {} is given twice", a.id));
        atom.push_back(a);
      });
      out.atom_style = style;
    } else if (name == "Masses") {
      if (have_masses) in.fail("a second Masses section");
      have_masses = true;
      section_rows(types, "Masses", "atom types", [&] {
        if (in.tokens().size() != 2) in.fail("a Masses line is \"type mass\"");
        const std::int64_t type = in.integer(0, "the atom type");
        if (type < 1 || type > static_cast<std::int64_t>(types))
          in.fail(fmt::format("atom type {} is not in 1..{} (the header's atom types)", type, types));
        const double m = in.number(1, "the mass");
        if (!(m > 0.0)) in.fail(fmt::format("the mass of atom type {} must be > 0, got {}", type, m));
        if (mass[static_cast<std::size_t>(type)] != 0.0) in.fail(fmt::format("atom type {} has two masses", type));
        mass[static_cast<std::size_t>(type)] = m;
      });
    } else if (name == "Velocities") {
      if (atom.empty()) in.fail("the Velocities section comes before the Atoms section");
      if (have_velocities) in.fail("a second Velocities section");
      have_velocities = true;
      std::vector<bool> seen(atom.size(), false);
      section_rows(atoms, "Velocities", "atoms", [&] {
        if (in.tokens().size() != 4) in.fail("a Velocities line is \"id vx vy vz\"");
        const std::int64_t id = in.integer(0, "the atom ID");
        const auto it = index.find(id);
        if (it == index.end()) in.fail(fmt::format("atom ID {} is not in the Atoms section", id));
        if (seen[it->second]) in.fail(fmt::format("atom ID {} has two velocities", id));
        seen[it->second] = true;
        for (int k = 0; k < 3; ++k) atom[it->second].v(k) = in.number(1 + static_cast<std::size_t>(k), "a velocity");
      });
    } else {
      // Bonds, Angles, Pair Coeffs, ...: nothing a rigid body needs (the
      // interaction is the scenario's; bonds within a molecule are rigid).
      if (!is_skipped_section(name))
        in.fail("\"" + printable(name) + "\" is not a section of a LAMMPS data file (Atoms, Masses, Velocities, "
                "Bonds, Pair Coeffs, ...)");
      if (name == "Ellipsoids" || name == "Lines" || name == "Triangles" || name == "Bodies")
        in.fail("the " + name + " section belongs to an atom_style without molecule IDs");
      more = in.next();
      while (more && !in.section()) more = in.next();
    }
  }
  if (atom.empty()) throw InvalidInput(file + ": no Atoms section");
  if (!have_masses) throw InvalidInput(file + ": no Masses section (lgvi needs each atom type's mass)");
  for (std::size_t t = 1; t <= types; ++t)
    if (mass[t] == 0.0) throw InvalidInput(fmt::format("{}: the Masses section gives no mass for atom type {}", file, t));

  // Molecules in increasing ID (an atom's place in it: increasing atom ID),
  // then the atoms of molecule 0, one body each.
  std::vector<std::size_t> order(atom.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const bool a0 = atom[a].molecule == 0, b0 = atom[b].molecule == 0;
    if (a0 != b0) return b0;
    return std::tie(atom[a].molecule, atom[a].id) < std::tie(atom[b].molecule, atom[b].id);
  });
  auto radius_of = [&](int type) {
    return radius.empty() ? 0.0 : radius.size() == 1 ? radius[0] : radius[static_cast<std::size_t>(type - 1)];
  };
  std::vector<Ball> balls;
  KindMatcher kinds;
  for (std::size_t first = 0; first < order.size();) {
    const Atom& head = atom[order[first]];
    std::size_t last = first + 1;
    if (head.molecule != 0)
      while (last < order.size() && atom[order[last]].molecule == head.molecule) ++last;
    balls.clear();
    for (std::size_t k = first; k < last; ++k) {
      const Atom& a = atom[order[k]];
      balls.push_back({a.x, mass[static_cast<std::size_t>(a.type)], radius_of(a.type), a.type});
      out.ids.atom.push_back(a.id);
    }
    out.ids.molecule.push_back(head.molecule);
    const std::string name = head.molecule != 0 ? fmt::format("mol{}", head.molecule) : fmt::format("atom{}", head.id);
    std::optional<RigidBody> body;
    try {
      body = RigidBody::from_balls(balls);
    } catch (const InvalidInput& e) {
      const std::string what = head.molecule != 0 ? fmt::format("molecule {} ({} atoms)", head.molecule, last - first)
                                                  : fmt::format("atom {} (molecule ID 0: a body of its own)", head.id);
      throw InvalidInput(fmt::format("{}: {}: {}", file, what, e.what()));
    }
    // The centre of mass as from_balls forms it (the same sum in the same
    // order), and the rigid projection of the velocities.
    double m = 0.0;
    Vector3<double> centre = Vector3<double>::Zero(), p = Vector3<double>::Zero(), l = Vector3<double>::Zero();
    for (const Ball& b : balls) {
      m += b.mass;
      centre += b.mass * b.position;
    }
    centre /= m;
    for (std::size_t k = first; k < last; ++k) {
      const Atom& a = atom[order[k]];
      const Ball& b = body->balls()[k - first];
      p += b.mass * a.v;
      l += b.mass * b.position.cross(a.v);
    }
    // The body in its principal axes, as LAMMPS takes it: R the eigenvectors
    // of J (a right-handed frame), the balls at R^T r_i, the attitude q with
    // pi(q) = R, and the body momentum R^T L (w = 2 R^T L).
    const Eigen::SelfAdjointEigenSolver<Matrix3<double>> es(body->inertia());
    Matrix3<double> axes = es.eigenvectors();
    if (axes.determinant() < 0.0) axes.col(0) = -axes.col(0);
    RigidBodyState s;
    s.q = S3d::from_rotation_matrix(axes);
    const Matrix3<double> r = s.q.matrix();
    balls.clear();
    for (const Ball& b : body->balls()) balls.push_back({r.transpose() * b.position, b.mass, b.radius, b.type});
    body = RigidBody::from_balls(balls);
    s.x = centre;
    s.p = p;
    // A linear molecule's L has no part along its axis but for atoms a
    // little off the line (within RigidBody::linear_threshold): removed, as
    // LAMMPS's omega has none.
    s.w = body->admissible_momentum(2.0 * (r.transpose() * l));
    out.kind.push_back(kinds.add(std::move(*body), s));
    out.names.push_back(name);
    out.states.push_back(s);
    first = last;
  }
  out.kinds = std::move(kinds.kinds);
  out.checksum = in.checksum();
  return out;
}

std::string file_checksum(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInput(printable(path) + ": cannot open the LAMMPS data file");
  Fnv1a h;
  char buffer[1 << 16];
  while (in) {
    in.read(buffer, sizeof buffer);
    h.add(buffer, static_cast<std::size_t>(in.gcount()));
  }
  return h.hex();
}

}  // namespace lgvi::app
