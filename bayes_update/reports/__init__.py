"""What the user reads and runs: figures, report files, the beam study
(``bayes-update reproduce``) and the command line."""
