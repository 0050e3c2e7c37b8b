"""Experiments of the MetaUrban paper as declarative files (`<name>.yaml` beside this module), a runner that trains
and evaluates what is missing and resumes killed runs (`curbside experiment run NAME --budget B`), and a report that
writes results.csv and a PNG beside the paper's numbers (`curbside experiment report NAME`)."""
