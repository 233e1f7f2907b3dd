#pragma once
// Frame features and similarity matrices of the motion graph (paper section 3.2.1), offline.
//
// A frame's feature vector stacks its root-free vertex positions X (3 #V) and
// sqrt(velocity_weight) times its vertex velocities V (3 #V), so that the frame distance of
// runtime/motion_graph.h is d = |f_a - f_b|^2 / #V. Velocities are measured in the root frame
// of the later frame, per capture frame (SimilarityDefinition::frame_time): for input i at
// sample u, V = (X(u) - A X(u - 1)) frame_time / (seconds(u) - seconds(u - 1)) with A the root
// motion from sample u - 1 to u. So the root's own motion counts (a walk and a jump moving at
// different speeds differ) but not where the character stands or which way it faces.
// A cyclic input's sample 0 looks back across the cycle's closure (sample F - 2 of the previous
// cycle); a one-shot input's sample 0 takes the velocity of sample 1.
#include <Eigen/Core>
#include <span>

#include "runtime/motion_graph.h"

namespace fourd::graph {

// 6 #V x F features of one input (reference `input` < N) of a space, column per sample.
Eigen::MatrixXf input_features(const MotionSpace& space, int input,
                               const SimilarityDefinition& definition);

// Features of the state the runtime plays at (t, w): the hybrid blend (Eq. 1) and its velocity
// over one capture frame back in time (a one-shot space's first frame looks forward instead).
// `scratch` from make_motion_sample(space).
Eigen::VectorXf played_state_features(const MotionSpace& space, double t, std::span<const float> w,
                                      const SimilarityDefinition& definition,
                                      MotionSample* scratch);

// Features of the linear blend of the inputs' features at (t, w): sum_i w_i f_i(t), f_i
// interpolated linearly between samples. The state Eq. 3 bounds exactly. `features` holds
// input_features of every input.
Eigen::VectorXf linear_state_features(std::span<const Eigen::MatrixXf> features, double t,
                                      std::span<const float> w);

// d = |a - b|^2 / #V [m^2].
double feature_distance(const Eigen::VectorXf& a, const Eigen::VectorXf& b);

// S^{st}_{ij}(u, v) for every input pair of two spaces of the same topology, normalised by the
// largest distance found. Throws InputError if the topologies differ or all frames coincide.
EdgeSimilarity build_edge_similarity(const MotionSpace& source, const MotionSpace& target,
                                     const SimilarityDefinition& definition);

// Area-weighted unit vertex normals of every reference frame of a space, stored as the positions
// are (runtime/blend.h): the inputs' in the layout of space.blend.frames, the other references'
// as fp16 displacements in that of space.blend.displacements (padding zero).
void reference_normals(const MotionSpace& space, AlignedFloats* normals,
                       AlignedHalfs* displacements);

}  // namespace fourd::graph
