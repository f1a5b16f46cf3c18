-- Statements of mocapdb.storage.retrieval (query by example over the archive).

-- name: motion_meta
SELECT motion_id, name, fps, n_frames FROM motions WHERE motion_id IN (SELECT unnest($ids)) ORDER BY motion_id;

-- name: motion_words
SELECT bits FROM features WHERE motion_id = $id ORDER BY frame;

-- name: archive_frames
SELECT count(*) AS n_motions, coalesce(sum(n_frames), 0) AS n_frames FROM motions;

-- name: motion_lengths
SELECT motion_id, n_frames FROM motions ORDER BY motion_id;

-- name: sample_words
-- the archive sample: each motion's frames whose (1-based) number is a multiple of $step
SELECT bits FROM features WHERE frame % $step = 0 ORDER BY motion_id, frame;

-- name: range_words
-- the words of frame ranges (mocap_ranges: ord, motion_id, first, last; 1-based inclusive), in range order
SELECT f.bits
FROM mocap_ranges r JOIN features f ON f.motion_id = r.motion_id AND f.frame BETWEEN r.first AND r.last
ORDER BY r.ord, f.frame;
