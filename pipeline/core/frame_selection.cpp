#include "pipeline/core/frame_selection.h"

#include <fmt/format.h>

#include <algorithm>

#include "pipeline/core/error.h"

namespace fourd {

bool FrameSelection::selects(const std::string& t, int frame) const {
  if (!take.empty() && take != t) return false;
  if (ranges.empty()) return true;
  return std::any_of(ranges.begin(), ranges.end(), [&](const FrameRange& r) {
    return frame >= r.first && (r.last < 0 || frame <= r.last);
  });
}

std::string FrameSelection::frames_text() const {
  std::string out;
  for (const FrameRange& r : ranges) {
    if (!out.empty()) out += ",";
    out += r.last < 0 ? fmt::format("{}:", r.first) : fmt::format("{}:{}", r.first, r.last);
  }
  return out;
}

std::string FrameSelection::job_suffix() const {
  if (whole()) return "";
  std::string frames;
  for (const FrameRange& r : ranges) {
    if (!frames.empty()) frames += "_";
    frames += r.last < 0 ? fmt::format("{}-end", r.first) : fmt::format("{}-{}", r.first, r.last);
  }
  return (take.empty() ? std::string("all") : take) + (frames.empty() ? "" : "." + frames);
}

std::string job_log_name(const std::string& stage, const FrameSelection& selection,
                         const std::string& part) {
  if (!part.empty()) return stage + "." + part + ".log";
  const std::string suffix = selection.job_suffix();
  return stage + (suffix.empty() ? "" : "." + suffix) + ".log";
}

FrameSelection parse_frame_selection(const std::string& take, const std::string& frames) {
  FrameSelection sel;
  sel.take = take;
  if (frames.empty()) return sel;
  std::size_t start = 0;
  while (start <= frames.size()) {
    std::size_t comma = frames.find(',', start);
    const std::string text = frames.substr(start, comma == std::string::npos ? std::string::npos
                                                                            : comma - start);
    FrameRange r;
    const std::size_t colon = text.find(':');
    try {
      std::size_t used = 0;
      if (colon == std::string::npos) {
        r.first = r.last = std::stoi(text, &used);
        if (used != text.size()) throw std::invalid_argument(text);
      } else {
        const std::string a = text.substr(0, colon), b = text.substr(colon + 1);
        if (!a.empty()) {
          r.first = std::stoi(a, &used);
          if (used != a.size()) throw std::invalid_argument(a);
        }
        if (!b.empty()) {
          r.last = std::stoi(b, &used);
          if (used != b.size()) throw std::invalid_argument(b);
        }
      }
    } catch (const std::exception&) {
      throw UsageError(fmt::format("--frames '{}': '{}' is not FIRST:LAST, FIRST: or N", frames,
                                   text));
    }
    if (r.first < 0 || (r.last >= 0 && r.last < r.first)) {
      throw UsageError(fmt::format("--frames '{}': '{}' is an empty or negative range", frames,
                                   text));
    }
    sel.ranges.push_back(r);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  std::sort(sel.ranges.begin(), sel.ranges.end(),
            [](const FrameRange& a, const FrameRange& b) { return a.first < b.first; });
  for (std::size_t i = 1; i < sel.ranges.size(); ++i) {
    const FrameRange& a = sel.ranges[i - 1];
    if (a.last < 0 || a.last >= sel.ranges[i].first) {
      throw UsageError(fmt::format("--frames '{}': ranges {}:{} and {}:{} overlap", frames, a.first,
                                   a.last < 0 ? std::string() : std::to_string(a.last),
                                   sel.ranges[i].first,
                                   sel.ranges[i].last < 0 ? std::string()
                                                          : std::to_string(sel.ranges[i].last)));
    }
  }
  return sel;
}

void check_frame_selection(const FrameSelection& selection, const CaptureIndex& capture) {
  if (selection.whole()) return;
  int frames = 0;
  std::string name;
  if (!selection.take.empty()) {
    const TakeCapture& take = capture.take(selection.take);  // InputError naming the takes
    frames = take.frame_count;
    name = "take " + take.name;
  } else {
    for (const TakeCapture& t : capture.takes) frames = std::max(frames, t.frame_count);
    name = "the longest take";
  }
  for (const FrameRange& r : selection.ranges) {
    const int last = r.last < 0 ? r.first : r.last;
    if (last >= frames) {
      throw InputError(fmt::format("--frames {}: {} has frames 0:{} ({} frames), so {}:{} lies "
                                   "outside it",
                                   selection.frames_text(), name, frames - 1, frames, r.first,
                                   r.last < 0 ? std::string() : std::to_string(r.last)));
    }
  }
}

}  // namespace fourd
