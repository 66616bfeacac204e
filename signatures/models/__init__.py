"""Shipped model bundles, one folder per radar preset (card.json + ONNX files)."""
