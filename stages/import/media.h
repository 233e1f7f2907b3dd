#pragma once
// Image sequences of a studio's capture, per camera: a video file (anything OpenCV's videoio
// with its FFmpeg backend reads: mp4, avi, mov, mkv...) or a folder of images with any naming,
// and which of their frames become which take's frames.
#include <filesystem>
#include <functional>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"

namespace fourd::import {

// One camera's sequence: a video, or image files in frame order.
struct Sequence {
  std::string camera;
  std::filesystem::path video;              // set for a video
  std::vector<std::filesystem::path> images;  // else the images, frame 0 first
  std::string describe() const;               // the video, or "<first image> (N images)"
};

// Files named after cameras: each file goes to the camera whose name its file name contains
// (the longest such name, so cam1 and cam10 are told apart); `explicit_files` ("cam01" ->
// path) come first. `what` names the files in errors ("video", "plate"). A camera with no file
// or a file with no camera is an InputError naming both lists. `several`: a camera may have
// more than one file (plates), in name order; else two files of one camera are an error.
std::map<std::string, std::vector<std::filesystem::path>> match_files_to_cameras(
    const std::vector<std::filesystem::path>& files,
    const std::map<std::string, std::filesystem::path>& explicit_files,
    const std::vector<Camera>& cameras, const std::string& what, bool several = false);

// The files of `paths`: files as given, folders listed (not recursively) for files whose
// extension is one of `extensions` (lower case, with the dot). Sorted naturally.
std::vector<std::filesystem::path> list_files(const std::vector<std::filesystem::path>& paths,
                                              const std::vector<std::string>& extensions);
const std::vector<std::string>& video_extensions();
const std::vector<std::string>& image_extensions();
bool is_video_file(const std::filesystem::path& path);

// Natural order: "img2" before "img10".
bool natural_less(const std::string& a, const std::string& b);

// The images of one camera from a pattern: "{camera}" stands for the camera's name anywhere;
// the file name part may hold "{frame}" (digits) or "{frame:04d}" (exactly 4 digits), ordered by
// that number, or "*" and "?" globs, ordered naturally. Throws InputError naming the pattern and
// the camera when nothing matches.
std::vector<std::filesystem::path> images_from_pattern(const std::string& pattern, const std::string& camera);

// Which frames of the source sequences a take is made of: FIRST..LAST inclusive (LAST -1: to the
// end of the shortest camera's sequence) every STEP frames, or a time range in seconds.
struct TakeSpec {
  std::string name;
  int first = 0;
  int last = -1;
  int step = 1;
  std::optional<double> from_seconds, to_seconds;  // instead of first/last, when given
};

// "walk", "walk=0:120", "walk=10:", "walk=1.5s:4s" (seconds). Throws UsageError.
TakeSpec parse_take(const std::string& text, int default_first, int default_last, int step,
                    std::optional<double> from_seconds, std::optional<double> to_seconds);

// The take with time ranges turned into frames at `fps`.
TakeSpec resolve_times(const TakeSpec& take, double fps);

// Frames per second of a video (CAP_PROP_FPS; 0 when unknown); throws InputError when it cannot
// be opened.
double video_fps(const std::filesystem::path& video, const std::string& camera);

// Reads every selected frame of `sequence` in order and hands it over: `sink(take index, output
// frame, source frame, image)`. `takes` must have times resolved. `flags` as cv::imread's for
// image files (videos are decoded to BGR). A closed range beyond the end of the sequence is an
// InputError naming the file, the camera and the take. Returns the sequence's frame count read
// (for open ranges: the frames there were).
using FrameSink = std::function<void(std::size_t take, int frame, int source_frame, const cv::Mat& image)>;
int read_sequence(const Sequence& sequence, const std::vector<TakeSpec>& takes, int flags,
                  const FrameSink& sink);

// Up to `count` frames sampled evenly from a video (all of them when it has fewer), BGR.
std::vector<cv::Mat> sample_video(const std::filesystem::path& video, const std::string& camera, int count);

}  // namespace fourd::import
