"""The data layer: data sets on disk and in memory (:mod:`.dataset`, :mod:`.folder`),
UFF58 files (:mod:`.uff`), excitation signals (:mod:`.signals`), spectra
(:mod:`.spectral`), the noise of each channel (:mod:`.noise`, from
:mod:`.periodic`, :mod:`.quiet` and :mod:`.lpm`), cheap channel checks
(:mod:`.checks`) and the inspection of a data set (:mod:`.inspect`).  Nothing
here knows a model."""
