"""The data layer: data sets on disk and in memory (:mod:`.dataset`), UFF58
files (:mod:`.uff`), excitation signals (:mod:`.signals`) and spectra
(:mod:`.spectral`).  Nothing here knows a model."""
