"""Monitoring: passages of trains in a measured acceleration record and the first mode identified from them."""
