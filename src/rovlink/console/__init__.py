"""``rovlink console``: commands as words or frames, replies decoded, completion and help from
the command table (needs the ``console`` extra)."""
