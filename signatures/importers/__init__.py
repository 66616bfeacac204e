"""Converters from foreign radar captures to recorded returns (docs/import.md): one module
per source format (`dca1000`, `array`), the shared dwell writer in `dwell`."""
