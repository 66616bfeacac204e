"""The bottom layer: the product's errors and exit codes, input parsing that every layer
shares (times, JSON with a nesting limit), and escaping of untrusted text. Imports
nothing of ours, so the radar, Remote ID, registry and decision layers all build on it."""
