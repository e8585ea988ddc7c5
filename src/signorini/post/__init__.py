"""Post-processing: result files (VTU/PVD for ParaView, CSV, JSON) and figures."""
