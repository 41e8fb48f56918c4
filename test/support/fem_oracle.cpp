#include "support/fem_oracle.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace deformable_flsm {

namespace {

/// Elements assembled per batch of triplets: bounds the triplet list's memory.
constexpr std::size_t kAssemblyBatch = 2048;
/// A pivot of the factorization below this fraction of the largest means a free rigid motion.
constexpr double kSingularPivot = 1e-12;
/// Inverse iterations for the lowest frequency, and the relative change that ends them early.
constexpr int kMaxInverseIterations = 500;
constexpr double kFrequencyTolerance = 1e-12;

using SparseMatrix = Eigen::SparseMatrix<double>;
using Matrix24 = Eigen::Matrix<double, 24, 24>;

std::string str(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

std::int64_t nodeKey(const Eigen::Vector3i& c) {
  constexpr std::int64_t kBits = 21;
  constexpr std::int64_t kMask = (std::int64_t{1} << kBits) - 1;
  return ((std::int64_t{c.z()} & kMask) << (2 * kBits)) | ((std::int64_t{c.y()} & kMask) << kBits) |
         (std::int64_t{c.x()} & kMask);
}

/// Stiffness of a cube of edge h of trilinear elasticity, 2x2x2 Gauss points:
/// K_e = sum_g B_g^T D B_g det J, B the 6 x 24 strain-displacement matrix (Voigt order xx, yy,
/// zz, yz, xz, xy, engineering shears), D the isotropic elasticity matrix (lambda, mu).
Matrix24 cubeStiffness(double h, const FemMaterial& material) {
  const double lambda = material.lameLambda(), mu = material.shearModulus();
  Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) D(i, j) = lambda;
    D(i, i) = lambda + 2.0 * mu;
    D(3 + i, 3 + i) = mu;
  }
  const double g = 1.0 / std::sqrt(3.0);
  const double detJ = std::pow(0.5 * h, 3);  // reference cube [-1, 1]^3 to [0, h]^3
  Matrix24 K = Matrix24::Zero();
  for (int gp = 0; gp < 8; ++gp) {
    const Eigen::Vector3d xi((gp & 1) ? g : -g, (gp & 2) ? g : -g, (gp & 4) ? g : -g);
    Eigen::Matrix<double, 6, 24> B = Eigen::Matrix<double, 6, 24>::Zero();
    for (int n = 0; n < 8; ++n) {
      const Eigen::Vector3d s((n & 1) ? 1.0 : -1.0, (n & 2) ? 1.0 : -1.0, (n & 4) ? 1.0 : -1.0);
      // dN/dx = dN/dxi * 2 / h, N = prod (1 + s_a xi_a) / 8
      Eigen::Vector3d d;
      d.x() = s.x() * (1 + s.y() * xi.y()) * (1 + s.z() * xi.z()) / 8.0;
      d.y() = s.y() * (1 + s.x() * xi.x()) * (1 + s.z() * xi.z()) / 8.0;
      d.z() = s.z() * (1 + s.x() * xi.x()) * (1 + s.y() * xi.y()) / 8.0;
      d *= 2.0 / h;
      B(0, 3 * n) = d.x();
      B(1, 3 * n + 1) = d.y();
      B(2, 3 * n + 2) = d.z();
      B(3, 3 * n + 1) = d.z();
      B(3, 3 * n + 2) = d.y();
      B(4, 3 * n) = d.z();
      B(4, 3 * n + 2) = d.x();
      B(5, 3 * n) = d.y();
      B(5, 3 * n + 1) = d.x();
    }
    K.noalias() += B.transpose() * D * B * detJ;
  }
  return K;
}

}  // namespace

void FemMaterial::validate() const {
  if (!std::isfinite(youngsModulus) || youngsModulus <= 0.0)
    throw std::invalid_argument("fem: youngs_modulus = " + str(youngsModulus) + ": expected a finite modulus > 0 (Pa)");
  if (!std::isfinite(poissonsRatio) || poissonsRatio < 0.0 || poissonsRatio >= 0.5)
    throw std::invalid_argument("fem: poissons_ratio = " + str(poissonsRatio) + ": expected a ratio in [0, 0.5)");
  if (!std::isfinite(density) || density <= 0.0)
    throw std::invalid_argument("fem: density = " + str(density) + ": expected a finite density > 0 (kg/m^3)");
}

struct FemOracle::Factorization {
  /// full K over every degree of freedom (both triangles)
  SparseMatrix K;
  bool ready = false;
  /// dof -> index among the free ones, -1 for a prescribed one
  std::vector<int> freeIndex;
  std::vector<int> freeDofs;
  Eigen::SimplicialLDLT<SparseMatrix> ldlt;
};

FemOracle::FemOracle(const Voxelization& voxels, const FemMaterial& material, int subdivision)
    : material_(material), subdivision_(subdivision) {
  material_.validate();
  if (voxels.cells.empty()) throw std::invalid_argument("fem: the voxelization has no occupied cells");
  if (voxels.fillFraction.size() != voxels.cells.size())
    throw std::invalid_argument("fem: fillFraction and cells differ in size");
  if (!(voxels.spacing > 0.0)) throw std::invalid_argument("fem: the voxelization's spacing must be > 0");
  if (subdivision < 1)
    throw std::invalid_argument("fem: subdivision = " + std::to_string(subdivision) + ": expected an integer >= 1");
  const int s = subdivision_;
  elementSize_ = voxels.spacing / s;
  std::unordered_map<std::int64_t, int> index;
  auto node = [&](const Eigen::Vector3i& c) {
    auto it = index.find(nodeKey(c));
    if (it != index.end()) return it->second;
    const int id = static_cast<int>(nodes_.size());
    index.emplace(nodeKey(c), id);
    nodes_.push_back(voxels.origin + elementSize_ * c.cast<double>());
    return id;
  };
  const std::size_t cells = voxels.cells.size();
  cellElements_.resize(cells);
  cellCentreNodes_.resize(cells);
  cellCentres_.resize(cells);
  for (std::size_t c = 0; c < cells; ++c) {
    const double fill = voxels.fillFraction[c];
    if (!(fill > 0.0) || fill > 1.0)
      throw std::invalid_argument("fem: cell " + std::to_string(c) + " has fill fraction " + str(fill) +
                                  ": expected (0, 1]");
    const Eigen::Vector3i base = s * voxels.cells[c];
    cellCentres_[c] = voxels.cellCenter(voxels.cells[c]);
    for (int k = 0; k < s; ++k)
      for (int j = 0; j < s; ++j)
        for (int i = 0; i < s; ++i) {
          std::array<int, 8> en;
          for (int n = 0; n < 8; ++n)
            en[n] = node(base + Eigen::Vector3i(i + (n & 1), j + ((n >> 1) & 1), k + ((n >> 2) & 1)));
          cellElements_[c].push_back(static_cast<int>(elementNodes_.size()));
          elementNodes_.push_back(en);
          elementFill_.push_back(fill);
        }
    // The cell centre is a node for even s, else the centre of the middle element.
    if (s % 2 == 0) {
      cellCentreNodes_[c].push_back(node(base + Eigen::Vector3i::Constant(s / 2)));
    } else {
      const int middle = cellElements_[c][static_cast<std::size_t>(((s / 2) * s + s / 2) * s + s / 2)];
      cellCentreNodes_[c].assign(elementNodes_[middle].begin(), elementNodes_[middle].end());
    }
  }
  prescribed_.assign(3 * nodes_.size(), 0);
  prescribedValue_.assign(3 * nodes_.size(), 0.0);
}

FemOracle::~FemOracle() = default;
FemOracle::FemOracle(FemOracle&&) noexcept = default;
FemOracle& FemOracle::operator=(FemOracle&&) noexcept = default;

std::size_t FemOracle::clampCellsInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  std::size_t count = 0;
  for (std::size_t c = 0; c < cellCentres_.size(); ++c) {
    if (!((cellCentres_[c].array() >= lo.array()).all() && (cellCentres_[c].array() <= hi.array()).all())) continue;
    ++count;
    for (int e : cellElements_[c])
      for (int n : elementNodes_[static_cast<std::size_t>(e)])
        for (int a = 0; a < 3; ++a) {
          prescribed_[3 * static_cast<std::size_t>(n) + a] = 1;
          prescribedValue_[3 * static_cast<std::size_t>(n) + a] = 0.0;
        }
  }
  if (factorization_) factorization_->ready = false;
  return count;
}

std::size_t FemOracle::fixNodesInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  std::size_t count = 0;
  for (int axis = 0; axis < 3; ++axis) count = prescribeInBox(lo, hi, axis, 0.0);
  return count;
}

std::size_t FemOracle::prescribeInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int axis,
                                      double value) {
  if (axis < 0 || axis > 2) throw std::invalid_argument("fem: axis " + std::to_string(axis) + ": expected 0, 1 or 2");
  if (!std::isfinite(value)) throw std::invalid_argument("fem: prescribed displacement must be finite");
  std::size_t count = 0;
  for (std::size_t n = 0; n < nodes_.size(); ++n) {
    if (!((nodes_[n].array() >= lo.array()).all() && (nodes_[n].array() <= hi.array()).all())) continue;
    prescribed_[3 * n + static_cast<std::size_t>(axis)] = 1;
    prescribedValue_[3 * n + static_cast<std::size_t>(axis)] = value;
    ++count;
  }
  if (factorization_) factorization_->ready = false;
  return count;
}

void FemOracle::clearConstraints() {
  std::fill(prescribed_.begin(), prescribed_.end(), 0);
  std::fill(prescribedValue_.begin(), prescribedValue_.end(), 0.0);
  if (factorization_) factorization_->ready = false;
}

const FemOracle::Factorization& FemOracle::factorization() const {
  if (!factorization_) {
    factorization_ = std::make_unique<Factorization>();
    const std::size_t dofs = 3 * nodes_.size();
    const Matrix24 Ke = cubeStiffness(elementSize_, material_);
    SparseMatrix& K = factorization_->K;
    K.resize(static_cast<Eigen::Index>(dofs), static_cast<Eigen::Index>(dofs));
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(kAssemblyBatch * 576);
    for (std::size_t e0 = 0; e0 < elementNodes_.size(); e0 += kAssemblyBatch) {
      triplets.clear();
      const std::size_t e1 = std::min(elementNodes_.size(), e0 + kAssemblyBatch);
      for (std::size_t e = e0; e < e1; ++e) {
        const auto& en = elementNodes_[e];
        for (int a = 0; a < 24; ++a)
          for (int b = 0; b < 24; ++b)
            triplets.emplace_back(3 * en[a / 3] + a % 3, 3 * en[b / 3] + b % 3, elementFill_[e] * Ke(a, b));
      }
      SparseMatrix batch(K.rows(), K.cols());
      batch.setFromTriplets(triplets.begin(), triplets.end());
      K += batch;
    }
  }
  Factorization& f = *factorization_;
  if (f.ready) return f;
  const std::size_t dofs = prescribed_.size();
  f.freeIndex.assign(dofs, -1);
  f.freeDofs.clear();
  for (std::size_t d = 0; d < dofs; ++d)
    if (!prescribed_[d]) {
      f.freeIndex[d] = static_cast<int>(f.freeDofs.size());
      f.freeDofs.push_back(static_cast<int>(d));
    }
  if (f.freeDofs.empty()) {
    f.ready = true;
    return f;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(f.K.nonZeros()) / 2 + 1);
  for (Eigen::Index col = 0; col < f.K.outerSize(); ++col) {
    const int fc = f.freeIndex[static_cast<std::size_t>(col)];
    if (fc < 0) continue;
    for (SparseMatrix::InnerIterator it(f.K, col); it; ++it) {
      const int fr = f.freeIndex[static_cast<std::size_t>(it.row())];
      if (fr >= fc) triplets.emplace_back(fr, fc, it.value());
    }
  }
  const auto nf = static_cast<Eigen::Index>(f.freeDofs.size());
  SparseMatrix Kff(nf, nf);
  Kff.setFromTriplets(triplets.begin(), triplets.end());
  f.ldlt.compute(Kff);
  const Eigen::VectorXd D = f.ldlt.info() == Eigen::Success ? f.ldlt.vectorD() : Eigen::VectorXd();
  if (D.size() == 0 || D.minCoeff() <= kSingularPivot * D.cwiseAbs().maxCoeff())
    throw std::runtime_error("fem: the stiffness matrix is singular: the clamps and prescribed displacements "
                             "leave a rigid motion of the object free; clamp cells or prescribe more components");
  f.ready = true;
  return f;
}

Eigen::Vector3d FemOracle::reactionInBox(const FemSolution& u, const Eigen::Vector3d& lo,
                                         const Eigen::Vector3d& hi) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t n = 0; n < nodes_.size(); ++n)
    if ((nodes_[n].array() >= lo.array()).all() && (nodes_[n].array() <= hi.array()).all()) sum += u.nodeReactions[n];
  return sum;
}

FemSolution FemOracle::solveStatic(const Eigen::Vector3d& bodyAcceleration) const {
  if (!bodyAcceleration.allFinite()) throw std::invalid_argument("fem: the body acceleration must be finite");
  const Factorization& f = factorization();
  const std::size_t dofs = prescribed_.size();
  Eigen::VectorXd load = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(dofs));
  const double elementVolume = std::pow(elementSize_, 3);
  for (std::size_t e = 0; e < elementNodes_.size(); ++e) {
    // consistent body force of a trilinear element under a uniform load: an eighth of its weight per node
    const Eigen::Vector3d fn = material_.density * elementFill_[e] * elementVolume / 8.0 * bodyAcceleration;
    for (int n : elementNodes_[e])
      for (int a = 0; a < 3; ++a) load[3 * n + a] += fn[a];
  }
  Eigen::VectorXd u = Eigen::Map<const Eigen::VectorXd>(prescribedValue_.data(), static_cast<Eigen::Index>(dofs));
  for (std::size_t d = 0; d < dofs; ++d)
    if (!prescribed_[d]) u[static_cast<Eigen::Index>(d)] = 0.0;
  if (!f.freeDofs.empty()) {
    const Eigen::VectorXd Ku = f.K * u;
    Eigen::VectorXd rhs(static_cast<Eigen::Index>(f.freeDofs.size()));
    for (std::size_t i = 0; i < f.freeDofs.size(); ++i)
      rhs[static_cast<Eigen::Index>(i)] = load[f.freeDofs[i]] - Ku[f.freeDofs[i]];
    const Eigen::VectorXd uf = f.ldlt.solve(rhs);
    for (std::size_t i = 0; i < f.freeDofs.size(); ++i) u[f.freeDofs[i]] = uf[static_cast<Eigen::Index>(i)];
  }
  FemSolution out;
  const Eigen::VectorXd Ku = f.K * u;
  out.strainEnergy = 0.5 * u.dot(Ku);
  out.nodeReactions.assign(nodes_.size(), Eigen::Vector3d::Zero());
  for (std::size_t d = 0; d < dofs; ++d)
    if (prescribed_[d]) out.nodeReactions[d / 3][static_cast<Eigen::Index>(d % 3)] = Ku[static_cast<Eigen::Index>(d)] - load[static_cast<Eigen::Index>(d)];
  out.nodeDisplacements.resize(nodes_.size());
  for (std::size_t n = 0; n < nodes_.size(); ++n) out.nodeDisplacements[n] = u.segment<3>(3 * static_cast<Eigen::Index>(n));
  out.cellDisplacements.resize(cellCentreNodes_.size());
  for (std::size_t c = 0; c < cellCentreNodes_.size(); ++c) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int n : cellCentreNodes_[c]) sum += out.nodeDisplacements[static_cast<std::size_t>(n)];
    out.cellDisplacements[c] = sum / static_cast<double>(cellCentreNodes_[c].size());
  }
  return out;
}

double FemOracle::lowestAngularFrequency() const {
  const Factorization& f = factorization();
  if (f.freeDofs.empty()) throw std::runtime_error("fem: every degree of freedom is prescribed: no vibration");
  const auto nf = static_cast<Eigen::Index>(f.freeDofs.size());
  // lumped mass per free dof: an eighth of each element's mass per node
  std::vector<double> nodeMass(nodes_.size(), 0.0);
  const double elementMass = material_.density * std::pow(elementSize_, 3) / 8.0;
  for (std::size_t e = 0; e < elementNodes_.size(); ++e)
    for (int n : elementNodes_[e]) nodeMass[static_cast<std::size_t>(n)] += elementMass * elementFill_[e];
  Eigen::VectorXd M(nf);
  for (Eigen::Index i = 0; i < nf; ++i) M[i] = nodeMass[static_cast<std::size_t>(f.freeDofs[static_cast<std::size_t>(i)] / 3)];
  // Inverse iteration x <- K^-1 M x: converges to the lowest mode (Rayleigh quotient for omega^2).
  Eigen::VectorXd x = Eigen::VectorXd::Ones(nf);
  double lambda = 0.0;
  for (int it = 0; it < kMaxInverseIterations; ++it) {
    const Eigen::VectorXd y = f.ldlt.solve(M.cwiseProduct(x));
    // Rayleigh quotient with K y = M x: y^T K y / y^T M y = y^T M x / y^T M y
    const double next = y.dot(M.cwiseProduct(x)) / y.dot(M.cwiseProduct(y));
    x = y / std::sqrt(y.dot(M.cwiseProduct(y)));
    if (it > 0 && std::abs(next - lambda) <= kFrequencyTolerance * next) {
      lambda = next;
      break;
    }
    lambda = next;
  }
  return std::sqrt(lambda);
}

namespace analytic {

double cantileverSelfWeightDeflection(double x, double length, double b, double t, double youngsModulus,
                                      double poissonsRatio, double density, double g) {
  const double A = b * t, I = b * t * t * t / 12.0;
  const double q = density * g * A;
  const double G = youngsModulus / (2.0 * (1.0 + poissonsRatio));
  const double kappa = 10.0 * (1.0 + poissonsRatio) / (12.0 + 11.0 * poissonsRatio);
  const double L = length;
  return q * x * x * (6.0 * L * L - 4.0 * L * x + x * x) / (24.0 * youngsModulus * I) +
         q * (L * x - 0.5 * x * x) / (kappa * G * A);
}

double cantileverSelfWeightTip(double length, double b, double t, double youngsModulus, double poissonsRatio,
                               double density, double g) {
  return cantileverSelfWeightDeflection(length, length, b, t, youngsModulus, poissonsRatio, density, g);
}

double columnSelfWeightTop(double height, double youngsModulus, double density, double g) {
  return density * g * height * height / (2.0 * youngsModulus);
}

double uniaxialLateralStrain(double axialStrain, double poissonsRatio) { return -poissonsRatio * axialStrain; }

double cantileverFirstBendingFrequency(double length, double t, double youngsModulus, double density) {
  constexpr double kBeta1 = 1.8751040687119611;  // first root of cos(b) cosh(b) = -1
  return kBeta1 * kBeta1 / (length * length) * std::sqrt(youngsModulus * t * t / (12.0 * density));
}

double hertzSphereForce(double radius, double depth, double youngsModulus, double poissonsRatio) {
  return 4.0 / 3.0 * youngsModulus / (1.0 - poissonsRatio * poissonsRatio) * std::sqrt(radius) * std::pow(depth, 1.5);
}

double hertzSphereOnBondedLayerForce(double radius, double depth, double thickness, double youngsModulus,
                                     double poissonsRatio) {
  const double nu = poissonsRatio, pi = 3.14159265358979323846;
  const double a0 = -(1.2876 - 1.4678 * nu + 1.3442 * nu * nu) / (1.0 - nu);
  const double b0 = (0.6387 - 1.0277 * nu + 1.5164 * nu * nu) / (1.0 - nu);
  const double chi = std::sqrt(radius * depth) / thickness;
  const double series = 1.0 - 2.0 * a0 / pi * chi + 4.0 * a0 * a0 / (pi * pi) * chi * chi -
                        8.0 / std::pow(pi, 3) * (a0 * a0 * a0 + 4.0 * pi * pi / 15.0 * b0) * std::pow(chi, 3) +
                        -16.0 * a0 / std::pow(pi, 4) * (a0 * a0 * a0 + 3.0 * pi * pi / 5.0 * b0) * std::pow(chi, 4);
  return hertzSphereForce(radius, depth, youngsModulus, poissonsRatio) * series;
}

}  // namespace analytic

}  // namespace deformable_flsm
