-- Statements of mocapdb.storage.retrieval (query by example over the archive).

-- name: motion_meta
SELECT motion_id, name, fps, n_frames FROM motions WHERE motion_id IN (SELECT unnest($ids)) ORDER BY motion_id;

-- name: motion_words
SELECT bits FROM features WHERE motion_id = $id ORDER BY frame;

-- name: archive_frames
SELECT count(*) AS n_motions, coalesce(sum(n_frames), 0) AS n_frames FROM motions;

-- name: motion_lengths
-- every motion's frames, and whether its feature rows are its frames 1…n (one without them is not ranked)
SELECT m.motion_id, m.n_frames, m.name,
       coalesce(f.n = m.n_frames AND f.lo = 1 AND f.hi = m.n_frames, m.n_frames = 0) AS complete
FROM motions m
LEFT JOIN (SELECT motion_id, count(*) AS n, min(frame) AS lo, max(frame) AS hi FROM features GROUP BY motion_id) f
    USING (motion_id)
ORDER BY m.motion_id;

-- name: sample_words
-- the archive sample: each motion's frames whose (1-based) number is a multiple of $step
SELECT bits FROM features WHERE frame % $step = 0 ORDER BY motion_id, frame;

-- name: range_words
-- the words of frame ranges (mocap_ranges: ord, motion_id, first, last; 1-based inclusive), in range order
SELECT f.bits
FROM mocap_ranges r JOIN features f ON f.motion_id = r.motion_id AND f.frame BETWEEN r.first AND r.last
ORDER BY r.ord, f.frame;
