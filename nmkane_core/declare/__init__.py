"""What a user declares: a named system, its parameters, visuals and stability sweep.
Plain data, validated when written; nothing here builds or compiles."""
