// ACL's own error between a raw clip and another version of it, for benchmarks/acl.py.
//
//   acl_error RAW.acl.sjson OTHER [SAMPLES.f32]
//
// OTHER is either a clip that acl_compressor compressed (`-out=OTHER.acl`) or a second raw clip
// (`.acl.sjson`, e.g. an mcz decode exported like RAW). Prints one JSON line: ACL's worst error
// (`calculate_compression_error` with `qvvf_transform_error_metric`, the metric acl_compressor
// reports) against RAW as it is (acl_compressor measures against RAW after its pre-processing),
// the worst track and time. With a compressed OTHER and SAMPLES.f32 it also writes the decoded
// local transforms there as ACL's error sees them (see write_samples): float32 (samples, tracks, 10)
// = rotation x y z w, translation, scale.
// acl_compressor itself cannot write a decoded clip, and the benchmark scores every codec's
// decode with the same Python code.

#include "acl/core/ansi_allocator.h"
#include "acl/core/floating_point_exceptions.h"
#include "acl/core/impl/debug_track_writer.h"
#include "acl/compression/track_error.h"
#include "acl/compression/transform_error_metrics.h"
#include "acl/decompression/decompress.h"
#include "acl/io/clip_reader.h"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

using namespace acl;

static bool ends_with(const char* text, const char* suffix)
{
	const size_t text_len = std::strlen(text);
	const size_t suffix_len = std::strlen(suffix);
	return text_len >= suffix_len && std::strcmp(text + text_len - suffix_len, suffix) == 0;
}

static bool read_bytes(const char* path, std::vector<char>& out)
{
	std::ifstream stream(path, std::ios::binary);
	if (!stream)
		return false;
	out.assign(std::istreambuf_iterator<char>(stream), std::istreambuf_iterator<char>());
	return !out.empty();
}

static bool read_raw_clip(iallocator& allocator, const char* path, track_array_qvvf& out)
{
	std::vector<char> text;
	if (!read_bytes(path, text))
	{
		std::fprintf(stderr, "%s: cannot read\n", path);
		return false;
	}
	clip_reader reader(allocator, text.data(), text.size() - 1);
	sjson_raw_track_list raw;
	if (reader.get_file_type() != sjson_file_type::raw_track_list || !reader.read_raw_track_list(raw)
		|| raw.track_list.get_track_type() != track_type8::qvvf)
	{
		const clip_reader_error error = reader.get_error();
		std::fprintf(stderr, "%s: line %u: not a raw transform track list (%s)\n", path, error.line, error.get_description());
		return false;
	}
	out = std::move(track_array_cast<track_array_qvvf>(raw.track_list));
	return true;
}

// Writes what ACL's error measures: every sample decoded as `calculate_compression_error` does (at the
// raw clip's sample times, interpolated where keyframes were stripped, default sub-tracks the raw
// clip's bind pose). acl::convert_track_list rounds to the nearest kept keyframe instead.
static bool write_samples(iallocator& allocator, const track_array_qvvf& raw, const compressed_tracks& compressed, const char* path)
{
	scope_disable_fp_exceptions fp_off;
	decompression_context<debug_transform_decompression_settings> context;
	context.initialize(compressed);
	const sample_rounding_policy rounding = compressed.has_database() || compressed.has_stripped_keyframes()
		? sample_rounding_policy::none : sample_rounding_policy::nearest;
	acl_impl::debug_track_writer writer(allocator, track_type8::qvvf, raw.get_num_tracks());
	writer.initialize_with_defaults(raw);

	std::ofstream stream(path, std::ios::binary | std::ios::trunc);
	for (uint32_t sample = 0; sample < raw.get_num_samples_per_track(); ++sample)
	{
		context.seek(rtm::scalar_min(float(sample) / raw.get_sample_rate(), raw.get_finite_duration()), rounding);
		context.decompress_tracks(writer);
		for (uint32_t index = 0; index < raw.get_num_tracks(); ++index)
		{
			const rtm::qvvf& transform = writer.read_qvv(index);
			float values[12];
			rtm::quat_store(transform.rotation, values);
			rtm::vector_store3(transform.translation, values + 4);
			rtm::vector_store3(transform.scale, values + 7);
			stream.write(reinterpret_cast<const char*>(values), 10 * sizeof(float));
		}
	}
	return bool(stream);
}

int main(int argc, char* argv[])
{
	if (argc < 3 || argc > 4 || !ends_with(argv[1], ".acl.sjson"))
	{
		std::fprintf(stderr, "usage: acl_error RAW.acl.sjson (COMPRESSED.acl | OTHER.acl.sjson) [SAMPLES.f32]\n");
		return 2;
	}
	ansi_allocator allocator;
	track_array_qvvf raw;
	if (!read_raw_clip(allocator, argv[1], raw))
		return 1;

	qvvf_transform_error_metric error_metric;
	track_error error;
	if (ends_with(argv[2], ".acl.sjson"))
	{
		track_array_qvvf other;
		if (!read_raw_clip(allocator, argv[2], other))
			return 1;
		error = calculate_compression_error(allocator, raw, other, error_metric);
	}
	else
	{
		std::vector<char> bytes;
		if (!read_bytes(argv[2], bytes))
		{
			std::fprintf(stderr, "%s: cannot read\n", argv[2]);
			return 1;
		}
		// A compressed track list must sit at a 16-byte aligned address: copy it to one.
		struct alignas(16) block { char bytes[16]; };
		std::vector<block> aligned((bytes.size() + sizeof(block) - 1) / sizeof(block));
		std::memcpy(aligned.data(), bytes.data(), bytes.size());
		const compressed_tracks* compressed = make_compressed_tracks(aligned.data());
		if (compressed == nullptr || compressed->get_size() != bytes.size() || compressed->is_valid(true).any())
		{
			std::fprintf(stderr, "%s: not a compressed ACL track list\n", argv[2]);
			return 1;
		}
		{
			scope_disable_fp_exceptions fp_off;
			decompression_context<debug_transform_decompression_settings> context;
			context.initialize(*compressed);
			error = calculate_compression_error(allocator, raw, context, error_metric);
		}
		if (argc == 4 && !write_samples(allocator, raw, *compressed, argv[3]))
		{
			std::fprintf(stderr, "%s: cannot write %s\n", argv[2], argv[3]);
			return 1;
		}
	}
	std::printf("{\"max_error\": %.9g, \"worst_track\": %u, \"worst_time\": %.9g, \"num_tracks\": %u, \"num_samples\": %u}\n",
		double(error.error), error.index, double(error.sample_time), raw.get_num_tracks(), raw.get_num_samples_per_track());
	return 0;
}
